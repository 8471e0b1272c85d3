"""How the estimators of finished runs started: when, how far from the truth, and how much of the travel the matcher
odometry they started on had measured. The start-up alignment fits that odometry to the first fixes, and a matcher that
reads a fraction of the travel (gicp from rest between parallel walls keeps its zero-velocity prior along them)
misplaces the start (docs/models.md, under "Through every blackout").

    .venv/bin/python benchmarks/startup.py RUN_DIR [RUN_DIR ...] [--window 30]

Nothing is run: each run directory's scenario.toml, groundtruth.tum and TUM files are read (a suite's run directories
are RUN/<scenario>/seed-<n>). Per estimator: the scenario time of its first estimate and how long after the run's start
it came, its horizontal and heading errors there against the truth, and the distance its matcher's odometry covered in
the `--window` seconds before that, over the true distance (1.00: the odometry measured the travel; - without a matcher).
"""

from __future__ import annotations

import argparse
import math
import sys
import tomllib
from pathlib import Path

import numpy as np

from riverbench.angles import wrap_angle
from scenarios.pipeline.files import read_tum


def heading(rows: np.ndarray) -> np.ndarray:
    """Planar heading (rad) of TUM rows: the direction of base_link's x axis on the water plane."""
    x, y, z, w = rows[:, 4], rows[:, 5], rows[:, 6], rows[:, 7]
    return np.arctan2(2.0 * (x * y + w * z), 1.0 - 2.0 * (y * y + z * z))


def truth_at(truth: np.ndarray, t: np.ndarray) -> np.ndarray:
    """True (x, y) at scenario times t, interpolated between the truth's rows."""
    return np.column_stack([np.interp(t, truth[:, 0], truth[:, 1]), np.interp(t, truth[:, 0], truth[:, 2])])


def travelled_share(odometry: np.ndarray, truth: np.ndarray, start: float, window_s: float) -> float:
    """Distance the odometry's rows covered in [start - window_s, start] over the true distance at the same times."""
    rows = odometry[(odometry[:, 0] >= start - window_s) & (odometry[:, 0] <= start)]
    if len(rows) < 2:
        return math.nan
    true_xy = truth_at(truth, rows[:, 0])
    true_distance = float(np.linalg.norm(np.diff(true_xy, axis=0), axis=1).sum())
    distance = float(np.linalg.norm(np.diff(rows[:, 1:3], axis=0), axis=1).sum())
    return distance / true_distance if true_distance > 0.0 else math.nan


def starts(run: Path, window_s: float) -> list[str]:
    """One table row per estimator of the run in `run`."""
    scenario = tomllib.loads((run / "scenario.toml").read_text(encoding="utf-8"))
    truth = read_tum(run / "groundtruth.tum", scenario_time=True)
    true_heading = np.unwrap(heading(truth))
    label = f"{scenario.get('name', run.name)} seed {scenario.get('seed', '?')}"
    tracks: dict[str, np.ndarray] = {}  # each TUM file read once, whichever estimators share it

    def track(name: str) -> np.ndarray:
        if name not in tracks:
            path = run / f"{name}.tum"
            tracks[name] = read_tum(path, scenario_time=True) if path.exists() else np.empty((0, 8))
        return tracks[name]

    rows = []
    for estimator in scenario.get("estimators", []):
        eid, mid = estimator["id"], estimator.get("matcher")
        est = track(eid)
        if not len(est):
            rows.append(f"| {label} | {eid} | never | | | | |")
            continue
        start = float(est[0, 0])
        error = float(np.hypot(*(est[0, 1:3] - truth_at(truth, np.array([start]))[0])))
        yaw_error = math.degrees(float(wrap_angle(heading(est[:1])[0] - np.interp(start, truth[:, 0], true_heading))))
        share = travelled_share(track(mid), truth, start, window_s) if mid else math.nan
        rows.append(
            f"| {label} | {eid} | {start:.1f} | {start - truth[0, 0]:.1f} | {error:.2f} | {yaw_error:+.1f} | "
            f"{'-' if math.isnan(share) else f'{share:.2f}'} |"
        )
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories (each with scenario.toml)")
    parser.add_argument("--window", type=float, default=30.0, help="seconds of odometry before each start [30]")
    args = parser.parse_args()
    missing = [str(r) for r in args.runs if not (r / "scenario.toml").is_file()]
    if missing:
        print(f"error: not a run directory (no scenario.toml): {', '.join(missing)}", file=sys.stderr)
        return 2
    print("| run | estimator | start t s | after the run's start s | position error m | heading error deg | odometry / true travel |")
    print("|---|---|---|---|---|---|---|")
    for run in args.runs:
        try:
            rows = starts(run, args.window)
        except (OSError, ValueError, KeyError) as exc:  # a missing or corrupt file of a run: one line naming it
            print(f"error: {run}: {type(exc).__name__}: {exc}", file=sys.stderr)
            return 2
        print("\n".join(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
