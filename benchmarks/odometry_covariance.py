"""How honest a matcher's covariance is: its per-scan errors against the exact relative lidar motion, beside the sigmas
it reports, at places along a world's route.

For each place, consecutive HDL-32E revolutions (noise on) are registered; every ok match with a covariance gives its
error (lateral y and yaw, in the previous scan's lidar frame) and its reported sigmas. Printed per place: the yaw
error's mean (a bias the chain integrates) and sd, the median reported yaw sigma, and the sd of the normalised error
(error / reported sigma: 1 for an honest covariance, below 1 for a pessimistic one); then, pooled over the places, the
p95 of the normalised error summed over runs of N consecutive scans, with a per-scan floor added in quadrature as the
filters add odom_floor_sigma_yaw_deg (fusion.params): what a dead-reckoning filter fed these matches would see over N
scans against what it assumes.

    .venv/bin/python benchmarks/odometry_covariance.py [--matcher gicp] [--stations 300,1000,...] [--scans 100] [--seed 1]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

import matcher
import sim
import worlds
from matcher.motion import pose_to_xyzrpy

STATIONS = (300.0, 1000.0, 1620.0, 2300.0, 2900.0, 3400.0, 3550.0, 3700.0, 4200.0, 4720.0)
"""charles_river route stations (m): open basin, bridges, the quickstart's quays, the dam lock."""
FLOORS_DEG = (0.0, 0.02, 0.05, 0.2)
SPANS = (1, 10, 50, 90)


def place(world, station: float, scans: int, name: str, seed: int) -> np.ndarray:
    """Rows (yaw error deg, reported yaw sigma deg, lateral error m, reported lateral sigma m) of the ok matches."""
    lidar = sim.HDL32E(seed=seed)
    traj = sim.Trajectory(world, start_m=station, seed=seed)
    m = matcher.create(name)
    rows, prev = [], None
    for k in range(scans):
        scan = lidar.scan(world, traj, 0.1 * k)
        r = m.register(scan)
        if prev is not None and r.ok and r.cov is not None:
            truth = np.linalg.inv(traj.lidar_pose(prev.stamp)) @ traj.lidar_pose(scan.stamp)
            e = pose_to_xyzrpy(np.linalg.inv(truth) @ r.T)
            sd = np.sqrt(np.clip(np.diag(r.cov), 0.0, None))
            rows.append((math.degrees(e[5]), math.degrees(sd[5]), e[1], sd[1]))
        if r.ok:
            prev = scan
    return np.asarray(rows, dtype=float).reshape(-1, 4)


def summed_z(places: list[np.ndarray], span: int, floor_deg: float) -> np.ndarray:
    """|sum of yaw errors| / sqrt(sum of (reported^2 + floor^2)) over every run of `span` consecutive matches."""
    out = []
    for rows in places:
        err, var = rows[:, 0], rows[:, 1] ** 2 + floor_deg**2
        for i in range(0, len(rows) - span + 1, max(1, span // 5)):
            out.append(abs(err[i : i + span].sum()) / math.sqrt(var[i : i + span].sum()))
    return np.asarray(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--world", default="charles_river")
    ap.add_argument("--matcher", default="gicp")
    ap.add_argument("--stations", default=",".join(f"{s:g}" for s in STATIONS))
    ap.add_argument("--scans", type=int, default=100)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    world = worlds.load(args.world)
    places = []
    print(f"{args.matcher} on {args.world}, {args.scans} revolutions a place, seed {args.seed}")
    print(f"{'station m':>9} {'n':>4} {'yaw mean':>9} {'yaw sd':>8} {'rep sd':>8} {'z sd':>6} {'lat sd m':>9} {'rep m':>7} (yaw in deg)")
    for station in (float(s) for s in args.stations.split(",")):
        rows = place(world, station, args.scans, args.matcher, args.seed)
        if not len(rows):
            print(f"{station:9.0f}    0 (no ok match with a covariance)")
            continue
        places.append(rows)
        y, ys, lat, lats = rows.T
        print(
            f"{station:9.0f} {len(rows):4d} {y.mean():+9.4f} {y.std():8.4f} {np.median(ys):8.4f} {np.std(y / ys):6.2f} "
            f"{lat.std():9.4f} {np.median(lats):7.4f}"
        )
    if not places:
        return
    print("summed yaw error over N consecutive matches / its assumed sigma, p95 (max), by per-scan floor:")
    print(f"{'N':>4} " + " ".join(f"{f'floor {f:g} deg':>18}" for f in FLOORS_DEG))
    for span in SPANS:
        cells = []
        for floor in FLOORS_DEG:
            z = summed_z(places, span, floor)
            cells.append(f"{np.percentile(z, 95):8.2f} ({z.max():6.2f})" if len(z) else f"{'n/a':>18}")
        print(f"{span:4d} " + " ".join(f"{c:>18}" for c in cells))


if __name__ == "__main__":
    main()
