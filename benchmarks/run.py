"""Scenario run speed and memory: real-time factor and peak memory of `riverbench run` on
charles_river stretches of several lengths, for the default stack (gicp + the four estimators), with all
four matchers (pcl6d, bev3dof, kiss_icp, gicp; the estimators on gicp), and with the MTi-630 IMU and its
compass: `inertial` adds an ekf fed both beside the default four (what a comparison of the two runs), `imu_ekf`
feeds them to the default ekf itself.

Each configuration runs in its own process (`riverbench run ... --no-report --quiet`), so its peak
memory is its own; the figures come from the run's metrics.json (wall time from world load to the
last file, peak RSS of the run's processes summed). Targets: default, inertial and imu_ekf stacks >= 5x real time, all
four matchers >= 1.5x, peak memory within 10% between 10 and 30 minutes (memory flat in length).

    .venv/bin/python benchmarks/run.py [--minutes 5 10 30] [--stacks default all4 inertial imu_ekf] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from scenarios.spec.scenario import default_lists

ALL_FOUR = (
    'matchers=[{id = "gicp", kind = "gicp"}, {id = "kiss_icp", kind = "kiss_icp"}, '
    '{id = "bev3dof", kind = "bev3dof"}, {id = "pcl6d", kind = "pcl6d"}]'
)
IMU_SENSORS = ["gnss", "odometry", "imu", "compass"]
IMU = ['imu={preset = "mti630"}', "compass={}"]  # issue 23's industrial IMU and its compass


def inline(value) -> str:
    """`value` as a TOML inline value, the syntax of `--set key=value`."""
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {inline(v)}" for k, v in value.items()) + "}"
    if isinstance(value, list):
        return "[" + ", ".join(inline(v) for v in value) + "]"
    return json.dumps(value)


def imu_stack(beside: bool) -> list[str]:
    """The default estimators with an ekf fed the IMU and compass: a fifth one beside the plain ekf (beside=True, to
    compare the two in one run) or the default ekf itself."""
    estimators = default_lists()["estimators"]
    if beside:
        estimators = [*estimators, {"id": "ekf_inertial", "kind": "ekf", "matcher": "gicp", "sensors": IMU_SENSORS}]
    else:
        estimators = [e | {"sensors": IMU_SENSORS} if e["id"] == "ekf" else e for e in estimators]
    return [f"estimators={inline(estimators)}", *IMU]


STACKS = {"default": [], "all4": [ALL_FOUR], "inertial": imu_stack(beside=True), "imu_ekf": imu_stack(beside=False)}
TARGET = {"default": 5.0, "all4": 1.5, "inertial": 5.0, "imu_ekf": 5.0}


def measure(minutes: float, stack: str, workers: int, scenario: str) -> dict:
    """Run one configuration in a fresh process and return its metrics.json 'run' table."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "run"
        sets = [f"stretch={{start_s = 0.0, end_s = {60.0 * minutes}}}", "expect=[]", *STACKS[stack]]
        cmd = [sys.executable, "-m", "scenarios.cli", "run", scenario, "--out", str(out), "--quiet", "--no-report", "--workers", str(workers)] + [
            a for s in sets for a in ("--set", s)
        ]
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode not in (0, 1):
            raise SystemExit(f"{stack} {minutes} min failed: {done.stderr.strip() or done.stdout.strip()}")
        metrics = json.loads((out / "metrics.json").read_text())
    return {"run": metrics["run"], "hz": {m: v["hz"] for m, v in metrics["matchers"].items()}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minutes", type=float, nargs="+", default=[5.0, 10.0, 30.0])
    parser.add_argument("--stacks", nargs="+", default=list(STACKS), choices=list(STACKS))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--scenario", default="charles_river")
    args = parser.parse_args()
    print(f"{args.scenario} from t=0, workers={args.workers}")
    print(f"{'stack':>8} {'minutes':>7} {'wall s':>7} {'x real time':>11} {'target':>6} {'peak MB':>8}  matcher Hz (median)")
    peaks: dict[str, dict[float, float]] = {}
    for stack in args.stacks:
        for minutes in args.minutes:
            r = measure(minutes, stack, args.workers, args.scenario)
            run = r["run"]
            peaks.setdefault(stack, {})[minutes] = run["peak_rss_mb"]
            hz = ", ".join(f"{m} {v:.0f}" for m, v in r["hz"].items() if v is not None)
            met = "met" if run["realtime_factor"] >= TARGET[stack] else "MISSED"
            print(f"{stack:>8} {minutes:7g} {run['wall_s']:7.1f} {run['realtime_factor']:11.2f} {met:>6} {run['peak_rss_mb']:8.0f}  {hz}", flush=True)
    for stack, by_length in peaks.items():
        if 10.0 in by_length and 30.0 in by_length:
            growth = by_length[30.0] / by_length[10.0] - 1.0
            print(f"{stack}: peak memory 30 min vs 10 min {growth:+.1%} ({'flat' if abs(growth) <= 0.10 else 'GROWS'})")


if __name__ == "__main__":
    main()
