"""Scan matchers on charles_river revolutions: rate (Hz, median of runs), points per scan, success, accuracy.

Consecutive HDL-32E revolutions (noise on) are simulated in two sets of places: approaching each
structure of the world (bridges, the dam lock: where the field study's matching worked) and evenly
spaced along the route (mostly open water and sea walls). Every matcher registers each sequence.
Hz = scans / summed `MatchResult.seconds` (wall clock) of one run, the median over runs; 'cpu Hz'
uses the process CPU time instead (all threads), a steadier figure on a shared machine.
Accuracy is the median error of the ok matches against the exact relative lidar motion; 'degen'
is the share of ok matches whose covariance flags a degenerate direction.

    .venv/bin/python benchmarks/matchers.py [--places 8] [--scans 15] [--runs 3] [--profile bev3dof]
Targets on 2 cores: bev3dof >= 100 Hz, pcl6d >= 10 Hz, kiss_icp and gicp >= 20 Hz.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

import matcher
import sim
import worlds
from matcher.motion import pose_to_xyzrpy

TARGET_HZ = {"pcl6d": 10.0, "bev3dof": 100.0, "kiss_icp": 20.0, "gicp": 20.0}


def structure_stations(world) -> list[float]:
    """Route stations 30 m before each structure recorded in world.params['structures']."""
    structures = world.params.get("structures", [])
    return [max(float(st["station_m"]) - 30.0, 0.0) for st in structures]


def simulate(world, stations, scans: int, sea_state: int, seed: int) -> list[tuple[sim.Trajectory, list]]:
    """One sequence of `scans` consecutive revolutions starting at each station."""
    lidar = sim.HDL32E(seed=seed)
    out = []
    for station in stations:
        traj = sim.Trajectory(world, start_m=float(station), sea_state=sea_state, seed=seed)
        out.append((traj, [lidar.scan(world, traj, 0.1 * k) for k in range(scans)]))
    return out


def run_once(name: str, sequences) -> dict:
    """One pass of matcher `name` over all sequences."""
    seconds, cpu, t_err, yaw_err, n_ok, n, n_degenerate = 0.0, 0.0, [], [], 0, 0, 0
    for traj, scans in sequences:
        m = matcher.create(name)
        for k, scan in enumerate(scans):
            c = time.process_time()
            r = m.register(scan)
            cpu += time.process_time() - c
            seconds += r.seconds
            if k == 0:
                continue
            n += 1
            if r.ok:
                n_ok += 1
                n_degenerate += bool(r.info.get("degenerate"))
                truth = np.linalg.inv(traj.lidar_pose(scans[k - 1].stamp)) @ traj.lidar_pose(scan.stamp)
                e = pose_to_xyzrpy(np.linalg.inv(truth) @ r.T)
                t_err.append(np.linalg.norm(e[:2] if name == "bev3dof" else e[:3]))
                yaw_err.append(abs(np.degrees(e[5])))
    n_scans = sum(len(s) for _, s in sequences)
    return {
        "hz": n_scans / seconds,
        "cpu_hz": n_scans / cpu,
        "success": n_ok / n,
        "degenerate": n_degenerate / n_ok if n_ok else float("nan"),
        "t_err": float(np.median(t_err)) if t_err else float("nan"),
        "yaw_err": float(np.median(yaw_err)) if yaw_err else float("nan"),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="charles_river")
    ap.add_argument("--places", type=int, default=8, help="sequences along the route (default 8)")
    ap.add_argument("--scans", type=int, default=15, help="consecutive revolutions per sequence (default 15)")
    ap.add_argument("--runs", type=int, default=3, help="repetitions; Hz is their median (default 3)")
    ap.add_argument("--sea-state", type=int, default=1, help="Douglas sea state of the vessel motion (default 1)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--matchers", default=",".join(matcher.available()), help="comma-separated names (default all)")
    ap.add_argument("--profile", default="", help="profile one matcher with pyinstrument instead of the table")
    args = ap.parse_args()

    world = worlds.load(args.world)
    sets = {
        "near structures": structure_stations(world),
        "along the route": list(np.linspace(100.0, world.route.length - 100.0, args.places)),
    }
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cpus, load {os.getloadavg()[0]:.2f}")
    for title, stations in sets.items():
        if not stations:
            continue
        t0 = time.perf_counter()
        sequences = simulate(world, stations, args.scans, args.sea_state, args.seed)
        points = [len(s) for _, scans in sequences for s in scans]
        print(
            f"\n{args.world}, {title}: {len(points)} revolutions in {len(stations)} sequences (simulated in "
            f"{time.perf_counter() - t0:.1f} s); points per scan median {np.median(points):.0f} (min {min(points)}, max {max(points)})"
        )
        if args.profile:
            from pyinstrument import Profiler

            profiler = Profiler()
            profiler.start()
            run_once(args.profile, sequences)
            profiler.stop()
            print(profiler.output_text(unicode=False, color=False))
            continue
        header = (
            f"{'matcher':9s} {'Hz':>7s} {'cpu Hz':>7s} {'target':>7s} {'pts/scan':>9s} {'success':>8s} {'degen':>6s} "
            f"{'t err m':>8s} {'yaw err deg':>12s}"
        )
        print(header)
        print("-" * len(header))
        for name in args.matchers.split(","):
            runs = [run_once(name, sequences) for _ in range(args.runs)]
            hz = float(np.median([r["hz"] for r in runs]))
            cpu_hz = float(np.median([r["cpu_hz"] for r in runs]))
            r = runs[0]
            print(
                f"{name:9s} {hz:7.1f} {cpu_hz:7.1f} {TARGET_HZ.get(name, float('nan')):7.0f} {np.median(points):9.0f} {r['success']:8.2f} "
                f"{r['degenerate']:6.2f} {r['t_err']:8.3f} {r['yaw_err']:12.3f}"
            )
    print(f"\nt err: median over ok matches; 3-D for 6-DoF matchers, planar (x, y) for bev3dof; load {os.getloadavg()[0]:.2f} at the end")


if __name__ == "__main__":
    main()
