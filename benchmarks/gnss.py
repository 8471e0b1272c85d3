"""GNSS receiver cost on a world's route: milliseconds per fix (trajectory pose, satellites, LOS and
multipath ray casts, WLS, receiver filter, truth), against the HDL-32E revolution time in the same
run, and the share GNSS adds to a run's LiDAR simulation time. Prints medians over rounds.

    .venv/bin/python benchmarks/gnss.py [--world charles_river] [--rounds 5] [--fixes 1000] [--revs 20]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import worlds
from sim import HDL32E, GnssReceiver, Trajectory


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="charles_river")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--fixes", type=int, default=1000, help="fixes per round (spread along the route)")
    parser.add_argument("--revs", type=int, default=20, help="LiDAR revolutions per round")
    args = parser.parse_args()

    world = worlds.load(args.world)
    traj = Trajectory(world)
    lidar = HDL32E()
    start = time.perf_counter()
    GnssReceiver().fix(world, traj, 0.0)  # builds the facade index and the ray-casting scene
    setup_s = time.perf_counter() - start
    lidar.scan(world, traj, 0.0)

    # Each round: one receiver driven at its output rate through 10 windows spread along the route.
    rate = GnssReceiver().rate_hz
    per_window = args.fixes // 10
    starts = np.linspace(0.0, traj.duration - per_window / rate - 1.0, 10)
    times = (starts[:, None] + np.arange(per_window) / rate).ravel()
    start = time.perf_counter()
    for t in times:
        traj.pose(t)
    pose_ms = (time.perf_counter() - start) / len(times) * 1e3
    stamps = np.linspace(0.0, traj.duration - 1.0, args.rounds * args.revs).reshape(args.rounds, args.revs)
    fix_ms, rev_ms = [], []
    for r in range(args.rounds):
        rx = GnssReceiver(seed=r)
        rx.fix(world, traj, times[0])  # per-world cache
        start = time.perf_counter()
        for t in times[1:]:
            rx.fix(world, traj, t)
        fix_ms.append((time.perf_counter() - start) / (len(times) - 1) * 1e3)
        start = time.perf_counter()
        for t0 in stamps[r]:
            lidar.scan(world, traj, float(t0))
        rev_ms.append((time.perf_counter() - start) / args.revs * 1e3)

    gnss, rev = float(np.median(fix_ms)), float(np.median(rev_ms))
    rx = GnssReceiver()
    share = rx.rate_hz * gnss / (lidar.config.rate_hz * rev)
    print(f"world {args.world}: {len(world.mesh.faces)} triangles; facade index + scene build {setup_s:.2f} s")
    print(
        f"GNSS fix:            {gnss:.3f} ms (median of {args.rounds} rounds x {len(times) - 1} fixes at "
        f"{rate:g} Hz, incl. trajectory.pose; rounds {', '.join(f'{m:.3f}' for m in fix_ms)})"
    )
    print(f"  of which trajectory.pose(t): {pose_ms:.3f} ms (the receiver asks for one pose per fix)")
    print(f"HDL-32E revolution:  {rev:.2f} ms (median of {args.rounds} rounds x {args.revs} revolutions)")
    print(f"GNSS at {rx.rate_hz:g} Hz adds {100 * share:.2f}% to LiDAR at {lidar.config.rate_hz:g} Hz (target < 5%)")


if __name__ == "__main__":
    main()
