"""Heading with and without the gyro: one run of a stretch with the ekf fed GPS and odometry, the same fed the IMU and
compass too, and two dead-reckoners started on the true pose (the matcher's odometry alone, and with the gyro); prints
the heading error (p95, max) of the two ekfs per GPS window (blackout, nlos, reacquisition, open: outside every window),
each estimator's added error through every blackout, and the yaw drift (final and worst) of the matcher's chained
odometry, the odometry-only ekf and the gyro-aided one (its gyro-bias prior the part's datasheet's).

    .venv/bin/python benchmarks/heading.py [--world charles_river] [--start-m 1620 --end-m 1800] [--seed 0]
        [--preset mti630] [--chase] [--out DIR]
"""

from __future__ import annotations

import argparse
import csv
import math
import tempfile
from pathlib import Path

import numpy as np

import scenarios
from scenarios.export.frames import open_stream
from scenarios.spec.library import validate
from sim.imu import PRESETS

ALL = ["gnss", "odometry", "imu", "compass"]
ESTIMATORS = {
    "ekf": None,  # the default sensors: gnss, odometry
    "ekf_inertial": ALL,
    "dr_odometry": ["odometry"],
    "dr_gyro": ["odometry", "imu"],
}
WINDOWS = ("blackout", "nlos", "reacquisition", "open")
CHASE = {"id": "chase", "kind": "chase", "boat": "runabout", "distance_m": 15.0, "lateral_m": -6.0}
"""library chase_boat's runabout astern."""


def read_tum(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(stamps, yaw rad) of a TUM file (qz, qw of a planar pose)."""
    data = np.loadtxt(path, ndmin=2)
    qx, qy, qz, qw = data[:, 4], data[:, 5], data[:, 6], data[:, 7]
    return data[:, 0], np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz))


def wrapped(a: np.ndarray) -> np.ndarray:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def windows(run: Path, t0: float) -> list[tuple[str, float, float]]:
    """(kind, start, end) of windows.csv, on the TUM files' UNIX clock (scenario time 0 is t0)."""
    with open(run / "windows.csv") as f:
        return [(r["kind"], t0 + float(r["start"]), t0 + float(r["end"])) for r in csv.DictReader(f)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="charles_river")
    parser.add_argument("--start-m", type=float, default=None)
    parser.add_argument("--end-m", type=float, default=None)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--preset", default="mti630", choices=["mti630", "bmi088"])
    parser.add_argument("--chase", action="store_true", help="with chase_boat's runabout astern")
    parser.add_argument("--out", type=Path, default=None, help="keep the run directory here")
    args = parser.parse_args()

    stretch = {k: v for k, v in (("start_m", args.start_m), ("end_m", args.end_m)) if v is not None}
    base = {"name": f"{args.world}_heading", "world": args.world, "seed": args.seed, "stretch": stretch}
    if args.chase:
        base["traffic"] = {"movers": [CHASE]}
    _, frames = open_stream(validate(base))
    pose = next(iter(frames)).base_pose  # the true start: where the dead-reckoners begin
    start = [float(pose[0, 3]), float(pose[1, 3]), math.degrees(math.atan2(pose[1, 0], pose[0, 0]))]
    estimators = []
    for eid, sensors in ESTIMATORS.items():
        spec: dict = {"id": eid, "kind": "ekf", "matcher": "gicp"}
        if sensors:
            spec["sensors"] = sensors
        if eid.startswith("dr_"):
            spec["params"] = {"initial_pose": start, "initial_sigma": [0.01, 0.01]}
        if eid == "dr_gyro":  # the gyro's bias as the part's datasheet knows it, so the gyro, not the odometry, holds the yaw
            spec["params"]["inertial"] = {"gyro_bias_sigma_dps": bias_sigma_dps(args.preset)}
        estimators.append(spec)
    scenario = validate(base | {"imu": {"preset": args.preset}, "matchers": [{"id": "gicp", "kind": "gicp"}], "estimators": estimators})
    out = args.out or Path(tempfile.mkdtemp(prefix="heading-")) / "run"
    result = scenarios.run(scenario, out, report=False)
    run = result.out_dir
    t_truth, yaw_truth = read_tum(run / "groundtruth.tum")
    errors = {}
    for eid in [*ESTIMATORS, "gicp"]:
        t, yaw = read_tum(run / f"{eid}.tum")
        keep = np.isin(t_truth, t)
        errors[eid] = (t_truth[keep], np.degrees(np.abs(wrapped(yaw - yaw_truth[keep]))), np.degrees(wrapped(yaw - yaw_truth[keep])))
    spans = windows(run, time_zero(run / "groundtruth.tum"))
    where = f"{args.world} {stretch or 'whole route'} seed {args.seed}{' with the chase boat' if args.chase else ''}, IMU {args.preset}"
    print(f"{where}: {t_truth[-1] - t_truth[0]:.0f} s, {len(t_truth)} scans")
    print("heading error, deg (p95 / max) per window    " + "  ".join(f"{k:>15s}" for k in WINDOWS))
    for eid in ("ekf", "ekf_inertial"):
        t, err, _ = errors[eid]
        inside = {kind: np.zeros(len(t), bool) for kind in WINDOWS}
        for kind, a, b in spans:
            if kind in inside:
                inside[kind] |= (t >= a) & (t < b)
        inside["open"] = ~np.any([inside[k] for k in WINDOWS[:-1]], axis=0)
        cells = [f"{np.percentile(err[m], 95):6.2f} / {err[m].max():5.2f}" if m.any() else f"{'-':>15s}" for m in (inside[k] for k in WINDOWS)]
        print(f"  {eid:40s} " + "  ".join(f"{c:>15s}" for c in cells))
    print("blackout (start-end s)   added error, m (max error - error at entry)   " + "  ".join(f"{e:>12s}" for e in ("ekf", "ekf_inertial")))
    with open(run / "windows.csv") as f:
        for row in csv.DictReader(f):
            if row["kind"] == "blackout":
                cells = "  ".join(f"{float(row[f'{e}.added'] or 'nan'):12.2f}" for e in ("ekf", "ekf_inertial"))
                print(f"  {float(row['start']):8.1f}-{float(row['end']):8.1f}                                             {cells}")
    print("yaw drift, deg (final / worst |error|): matcher odometry chained from the truth, ekf on odometry alone, ekf on odometry + gyro")
    for eid in ("gicp", "dr_odometry", "dr_gyro"):
        _, err, signed = errors[eid]
        print(f"  {eid:12s} {signed[-1]:+7.2f} / {err.max():6.2f}")
    print(f"run directory: {run}")


def bias_sigma_dps(preset: str) -> float:
    """1 sigma of a part's gyro bias at power-on, deg/s: its turn-on bias and its in-run stability (sim.imu.PRESETS)."""
    gyro = PRESETS[preset]["gyro"]
    return math.hypot(gyro["turn_on_bias_dps"], gyro["bias_instability_dph"] / 3600.0)


def time_zero(tum: Path) -> float:
    """The UNIX time of scenario time 0, from a run's TUM header ("# time zero (UNIX s): ...")."""
    with open(tum) as f:
        for line in f:
            if line.startswith("# time zero"):
                return float(line.split(":", 1)[1].split()[0])
    raise ValueError(f"{tum}: no time zero line")


if __name__ == "__main__":
    main()
