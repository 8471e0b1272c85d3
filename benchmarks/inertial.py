"""What an IMU and a compass add to the ekf (and the pf): one run of a world's stretch with the same ekf fed GPS and
odometry, + the industrial IMU, + its compass; prints per GPS blackout the error each added over its error at the
outage's start, and the heading error (p95, max) of each estimator and of the compass itself.

    .venv/bin/python benchmarks/inertial.py [--world charles_river] [--start-m 1620 --end-m 1800] [--preset mti630] [--out DIR]
"""

from __future__ import annotations

import argparse
import csv
import json
import tempfile
from pathlib import Path

import scenarios
from scenarios.spec.library import validate

FED = {"ekf": None, "ekf_imu": ["gnss", "odometry", "imu"], "ekf_imu_compass": ["gnss", "odometry", "imu", "compass"]}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="charles_river")
    parser.add_argument("--start-m", type=float, default=None)
    parser.add_argument("--end-m", type=float, default=None)
    parser.add_argument("--preset", default="mti630", choices=["mti630", "bmi088"])
    parser.add_argument("--pf", action="store_true", help="also a pf fed all four sensors")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=None, help="keep the run directory here")
    args = parser.parse_args()

    stretch = {k: v for k, v in (("start_m", args.start_m), ("end_m", args.end_m)) if v is not None}
    estimators = [{"id": eid, "kind": "ekf", **({"sensors": s} if s else {})} for eid, s in FED.items()]
    if args.pf:
        estimators.append({"id": "pf_imu_compass", "kind": "pf", "sensors": FED["ekf_imu_compass"]})
    scenario = validate(
        {
            "name": f"{args.world}_inertial",
            "world": args.world,
            "seed": args.seed,
            "stretch": stretch,
            "imu": {"preset": args.preset},
            "matchers": [{"id": "gicp", "kind": "gicp"}],
            "estimators": estimators,
        }
    )
    out = args.out or Path(tempfile.mkdtemp(prefix="inertial-")) / "run"
    result = scenarios.run(scenario, out, report=False)
    metrics = json.loads((result.out_dir / "metrics.json").read_text())
    ids = [e["id"] for e in estimators]
    print(f"{args.world} {stretch or 'whole route'} seed {args.seed}, IMU {args.preset}: {metrics['run']['sim_s']:.0f} s")
    print("blackout (start-end s)  " + "  ".join(f"{i:>16s}" for i in ids) + "   (added error, m: max error - error at entry)")
    with open(result.out_dir / "windows.csv") as f:
        for row in csv.DictReader(f):
            if row["kind"] == "blackout":
                cells = "  ".join(f"{float(row[f'{i}.added'] or 'nan'):16.2f}" for i in ids)
                print(f"{float(row['start']):8.1f}-{float(row['end']):8.1f}      {cells}")
    for i in ids:
        e = metrics["estimators"][i]
        print(f"{i:16s} ape p95 {e['ape']['p95']:6.2f} m  yaw p95 {e['yaw']['p95']:5.2f} max {e['yaw']['max']:5.2f} deg  compass {e.get('compass')}")
    c = metrics["compass"]
    print(f"compass itself: yaw p95 {c['yaw']['p95']:.2f} max {c['yaw']['max']:.2f} deg, off by > 3 deg for {c['disturbed_s']:.1f} s")
    print(f"run directory: {result.out_dir}")


if __name__ == "__main__":
    main()
