"""Scenario run speed and memory: real-time factor and peak memory of `riverbench run` on
charles_river stretches of several lengths, for the default stack (gicp + the four estimators), with all
four matchers (pcl6d, bev3dof, kiss_icp, gicp; the estimators on gicp), and with the MTi-630 IMU and its
compass: `inertial` adds an ekf fed both beside the default four (what a comparison of the two runs), `imu_ekf`
feeds them to the default ekf itself.

Each configuration runs in its own process (`riverbench run ... --no-report --quiet`), so its peak
memory is its own; the figures come from the run's metrics.json (wall time from world load to the
last file, peak RSS of the run's processes summed). Targets: default, inertial and imu_ekf stacks >= 5x real time, all
four matchers >= 1.5x, peak memory within 10% between 10 and 30 minutes (memory flat in length).

    .venv/bin/python benchmarks/run.py [--minutes 5 10 30] [--stacks default all4 inertial imu_ekf] [--workers 2] [--rounds 3]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

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
    parser.add_argument(
        "--rounds", type=int, default=1, help="runs of every configuration, interleaved round by round (medians the machine's drift cannot bias)"
    )
    args = parser.parse_args()
    if args.rounds < 1:
        parser.error(f"--rounds must be at least 1, got {args.rounds}")
    print(f"{args.scenario} from t=0, workers={args.workers}, {args.rounds} round(s)")
    print(f"{'round':>5} {'stack':>8} {'minutes':>7} {'wall s':>7} {'x real time':>11} {'target':>6} {'peak MB':>8}  matcher Hz (median)")
    runs: dict[tuple[str, float], list[dict]] = {}
    for round_no in range(1, args.rounds + 1):
        for stack in args.stacks:
            for minutes in args.minutes:
                r = measure(minutes, stack, args.workers, args.scenario)
                run = r["run"]
                runs.setdefault((stack, minutes), []).append(run)
                hz = ", ".join(f"{m} {v:.0f}" for m, v in r["hz"].items() if v is not None)
                met = "met" if run["realtime_factor"] >= TARGET[stack] else "MISSED"
                factor, wall, peak = run["realtime_factor"], run["wall_s"], run["peak_rss_mb"]
                print(f"{round_no:5d} {stack:>8} {minutes:7g} {wall:7.1f} {factor:11.2f} {met:>6} {peak:8.0f}  {hz}", flush=True)
    if args.rounds > 1:
        summarise(runs)
    for stack in args.stacks:
        if (stack, 10.0) in runs and (stack, 30.0) in runs:
            peak = {m: np.median([r["peak_rss_mb"] for r in runs[stack, m]]) for m in (10.0, 30.0)}
            growth = peak[30.0] / peak[10.0] - 1.0
            print(f"{stack}: peak memory 30 min vs 10 min {growth:+.1%} ({'flat' if abs(growth) <= 0.10 else 'GROWS'})")


def summarise(runs: dict[tuple[str, float], list[dict]]) -> None:
    """Median real-time factor of each configuration over the rounds, and its wall time against the default stack's in
    the same rounds (median of the per-round ratios: what the stack costs beyond the default, whatever the machine's speed)."""
    print(f"{'stack':>8} {'minutes':>7} {'median x':>8} {'min':>5} {'max':>5} {'target':>6}  wall / default's (median of rounds)")
    for (stack, minutes), rs in runs.items():
        factors = [r["realtime_factor"] for r in rs]
        median = float(np.median(factors))
        default = runs.get(("default", minutes))
        ratio = f"{np.median([r['wall_s'] / d['wall_s'] for r, d in zip(rs, default, strict=True)]):.3f}" if default and stack != "default" else ""
        met = "met" if median >= TARGET[stack] else "MISSED"
        print(f"{stack:>8} {minutes:7g} {median:8.2f} {min(factors):5.2f} {max(factors):5.2f} {met:>6}  {ratio}")


if __name__ == "__main__":
    main()
