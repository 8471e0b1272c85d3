"""Fusion through GPS outages: the error each estimator adds under bridges and through the receiver's
wrong smoothed estimate after them, against gps_only and hdop_switch, with exact truth.

The real stack (world, sim.Trajectory, sim.HDL32E, sim.GnssReceiver, matcher --matcher) is
simulated once per seed over the whole route (or --t-start/--t-end) and recorded
(benchmarks/stream_record.py; reused from --out); gps_only, hdop_switch, ekf and pf at their
defaults are replayed over all of it, so that each meets an outage with the state the route gave it.
With --margin M only the stretches around the outages are simulated (found by a pass of the receiver
alone; each from M s before an outage to --after s past it, overlapping ones merged): about 3x
cheaper on charles_river, and each estimator meets the outage after M s of the route, not all of it.
Over a stretch every estimator starts cold (its own GPS alignment, as at the route's start), or with
--start-from-truth at the true pose of the stretch's first scan (fusion's initial_pose, default
initial_sigma): a cold start near canal_lock's buildings can align tens of degrees off, which is no
part of an outage, while a true start begins well inside the GPS error the route would have left.
On canal_lock prefer the whole route (it is short): both starts near its buildings misjudge the
outages at 336-342 s and 445-453 s (cold: 11-41 m added, with the old matcher and the new alike;
the whole route: 1.8 and 0.0 m on seed 0).
The receiver-only pass's outage windows are kept in --out as JSON next to the recordings.
Every stretch without a measured fix (GGA 0 or 6) of at least --min-outage s is an outage. Per
outage and estimator the table gives the error when the outage begins (at its first scan), the max
and mean horizontal error during it and in the --after s once fixes return, and the added error:
the max over the outage and the --after s minus the error when it began. The --target estimator
passes an outage when it adds at most --limit m. Then the whole route's median and p95, and a
summary of the target's added error per outage and seed. A PNG per outage goes to --out.

    .venv/bin/python benchmarks/outages.py [--world charles_river] [--matcher gicp] [--seeds 0 1 2]
        [--after 20] [--limit 1.5] [--margin 60] [--set world.some_param=value ...]

`--set section.key=value` (world, vessel, lidar, gnss, matcher) changes what is simulated, e.g. to
measure again once a world gains trees or moving boats; it is part of the recording's name.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from stream_record import (
    Recording,
    add_recording_args,
    build,
    code_digest,
    load_or_record,
    parse_settings,
    replay,
    settings_tag,
)

import fusion

NAMES = ("gps_only", "hdop_switch", "ekf", "pf")


@dataclass(frozen=True)
class OutageError:
    """One estimator's horizontal errors (m) over one outage and the `after` s that follow it."""

    start: float
    out_max: float
    out_mean: float
    after_max: float
    after_mean: float

    @property
    def added(self) -> float:
        """Max error in the outage and after it, minus the error when the outage began."""
        return max(self.out_max, self.after_max) - self.start


def outage_windows(fix_stamp: np.ndarray, quality: np.ndarray, min_s: float) -> list[tuple[float, float]]:
    """[start, end) of every stretch without a measured fix lasting at least min_s."""
    measured = np.isin(quality, (1, 2, 4, 5))
    windows, start = [], None
    for t, ok in zip(fix_stamp, measured):
        if not ok and start is None:
            start = t
        elif ok and start is not None:
            if t - start >= min_s:
                windows.append((float(start), float(t)))
            start = None
    return windows


def outage_error(t: np.ndarray, error: np.ndarray, window: tuple[float, float], after_s: float) -> OutageError:
    """Errors of one estimator (at scan times t) over `window` and the after_s s that follow it."""
    a, b = window
    out, after = (t >= a) & (t < b), (t >= b) & (t < b + after_s)
    first = int(np.searchsorted(t, a))
    start = float(error[first]) if first < len(t) else float("nan")
    stats = [
        (float(np.nanmax(e)), float(np.nanmean(e))) if len(e) and np.isfinite(e).any() else (float("nan"),) * 2 for e in (error[out], error[after])
    ]
    return OutageError(start, *stats[0], *stats[1])


def _verdict(e: OutageError, limit: float) -> str:
    """'pass' / 'FAIL' against the limit; 'n/a' when the estimator had no estimate when the outage began."""
    return "n/a" if not np.isfinite(e.added) else "pass" if e.added <= limit else "FAIL"


def stretches(args, seed: int, settings: dict) -> list[tuple[float, float | None]]:
    """Spans to record: --t-start/--t-end, or with --margin each outage of a receiver-only pass over
    the route from margin s before it to --after s past it, overlapping spans merged."""
    if args.margin is None:
        return [(args.t_start, args.t_end)]
    duration, windows = receiver_outages(args, seed, settings)
    spans: list[tuple[float, float | None]] = []
    for a, b in windows:
        lo, hi = max(0.0, a - args.margin), min(duration, b + args.after + 1.0)
        if spans and lo <= spans[-1][1]:
            spans[-1] = (spans[-1][0], hi)
        else:
            spans.append((lo, hi))
    return spans


def receiver_outages(args, seed: int, settings: dict) -> tuple[float, list[tuple[float, float]]]:
    """The route's duration and its outage windows from the receiver alone (cached in --out)."""
    path = Path(args.out) / f"outages_{args.world}_s{seed}_min{args.min_outage:g}{settings_tag(settings)}_{code_digest()}.json"
    if path.exists():
        cached = json.loads(path.read_text())
        return cached["duration"], [tuple(w) for w in cached["windows"]]
    stream = build(args.world, seed, settings)
    duration = stream.trajectory.duration
    stamps = stream.receiver.epochs(duration)
    quality = np.array([stream.receiver.fix(stream.scene, stream.trajectory, t).quality for t in stamps])
    windows = outage_windows(stamps, quality, args.min_outage)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    tmp.write_text(json.dumps({"duration": duration, "windows": windows}))
    tmp.replace(path)
    return duration, windows


def start_pose(rec: Recording, from_truth: bool) -> dict:
    """initial_pose (x, y, yaw deg) of the true pose at a stretch's first scan if asked for and not at the route's start; else {}."""
    if not from_truth or rec.t_start <= 0.0:
        return {}
    x, y, _, yaw = next(item[3] for item in rec.items if item[0] == "scan")
    return {"initial_pose": (float(x), float(y), math.degrees(yaw))}


def run_seed(args, seed: int, settings: dict) -> list[tuple[tuple[float, float], OutageError]]:
    """Each stretch of one seed (`stretches`) recorded or reused, the estimators replayed, its table printed; the target's errors per outage."""
    return [row for span in stretches(args, seed, settings) for row in run_stretch(args, seed, settings, *span)]


def run_stretch(args, seed: int, settings: dict, t_start: float, t_end: float | None) -> list[tuple[tuple[float, float], OutageError]]:
    """Record (or reuse) one stretch, replay the estimators, print its table; the target's errors per outage."""
    rec = load_or_record(Path(args.out), args.world, args.matcher, seed, t_start, t_end, settings)
    run = replay(rec, {n: fusion.create(n, matcher=args.matcher, **start_pose(rec, args.start_from_truth)) for n in NAMES})
    quality = np.array([f.quality for f in run["fix"]])
    windows = outage_windows(run["fix_stamp"], quality, args.min_outage)
    print(
        f"\n{args.world} [{rec.t_start:.0f}, {rec.t_end:.0f}] s, matcher {args.matcher}, seed {seed}: "
        f"{len(windows)} outage(s) >= {args.min_outage} s: " + ", ".join(f"{a:.1f}-{b:.1f}" for a, b in windows)
    )
    t = run["scan_stamp"]
    error = {n: np.hypot(*(run["estimate"][n][:, :2] - run["truth"][:, :2]).T) for n in NAMES}
    fix_error = np.array([np.hypot(*f.truth.error[:2]) for f in run["fix"]])
    print(f"{'outage':>13} {'estimator':>12} {'start':>6} {'out max':>8} {'out mean':>8} {'after max':>9} {'after mean':>10} {'added':>6}")
    target = []
    for a, b in windows:
        for n in NAMES:
            e = outage_error(t, error[n], (a, b), args.after)
            verdict = _verdict(e, args.limit) if n == args.target else ""
            print(
                f"{a:6.1f}-{b:6.1f} {n:>12} {e.start:6.2f} {e.out_max:8.2f} {e.out_mean:8.2f} "
                f"{e.after_max:9.2f} {e.after_mean:10.2f} {e.added:6.2f} {verdict}"
            )
            if n == args.target:
                target.append(((a, b), e))
        span = (t >= a - args.before) & (t < b + args.after)
        fspan = (run["fix_stamp"] >= a - args.before) & (run["fix_stamp"] < b + args.after)
        plot_errors(
            t[span],
            {n: error[n][span] for n in NAMES},
            run["fix_stamp"][fspan],
            fix_error[fspan],
            (a, b),
            Path(args.out) / f"fusion_outage_{args.world}_s{seed}_{a:.0f}.png",
            f"{args.world} seed {seed}: outage {a:.1f}-{b:.1f} s ({args.matcher})",
        )
    print(f"whole recording ({len(t)} scans): horizontal error at scan times, m")
    for n in NAMES:
        print(f"{n:>12} median {np.nanmedian(error[n]):6.2f}  p95 {np.nanpercentile(error[n], 95):6.2f}  max {np.nanmax(error[n]):6.2f}")
    return target


def plot_errors(t: np.ndarray, error: dict, fix_t: np.ndarray, fix_error: np.ndarray, window, path: Path, title: str) -> None:
    """Each estimator's horizontal error over the outage's span, the fixes' true errors, the outage shaded."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(10, 4.5))
    for n, e in error.items():
        ax.plot(t, e, label=n, lw=1.2)
    ax.plot(fix_t, fix_error, "k.", ms=2, label="fix true error")
    ax.axvspan(*window, color="0.85", label="no measured fix")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("horizontal error (m)")
    ax.set_ylim(0, min(30.0, max(5.0, 1.1 * float(np.nanmax([np.nanmax(e) for e in error.values()])))))
    ax.set_title(title)
    ax.legend(ncol=3, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_recording_args(parser)
    parser.add_argument("--seeds", type=int, nargs="+", default=None, help="seeds to run in turn (default: --seed)")
    parser.add_argument("--t-start", type=float, default=0.0, help="record from this time, s (default 0: the whole route)")
    parser.add_argument("--t-end", type=float, default=None, help="record up to this time, s (default: the route's end)")
    parser.add_argument(
        "--margin", type=float, default=None, help="simulate only the stretches from this many s before each outage to --after s past it"
    )
    parser.add_argument(
        "--start-from-truth", action="store_true", help="over a stretch, start every estimator at the true pose instead of its own GPS alignment"
    )
    parser.add_argument("--min-outage", type=float, default=2.0)
    parser.add_argument("--before", type=float, default=40.0, help="plotted seconds before an outage")
    parser.add_argument("--after", type=float, default=20.0, help="seconds after an outage that count towards its error")
    parser.add_argument("--target", default="ekf", choices=NAMES, help="estimator judged against --limit")
    parser.add_argument("--limit", type=float, default=1.5, help="most error the target may add through an outage, m")
    args = parser.parse_args()
    try:
        settings = parse_settings(args.settings)
    except ValueError as err:
        parser.error(str(err))
    rows = []
    for seed in args.seeds if args.seeds is not None else [args.seed]:
        rows += [(seed, window, e) for window, e in run_seed(args, seed, settings)]
    print(
        f"\n{args.target} added error per outage ({args.world}, matcher {args.matcher}, after {args.after:g} s, "
        f"limit {args.limit:g} m{', ' + ' '.join(args.settings) if args.settings else ''})"
    )
    print(f"{'seed':>4} {'outage':>13} {'start':>6} {'max':>6} {'added':>6}")
    for seed, (a, b), e in rows:
        print(f"{seed:4d} {a:6.1f}-{b:6.1f} {e.start:6.2f} {max(e.out_max, e.after_max):6.2f} {e.added:6.2f} {_verdict(e, args.limit)}")
    judged = [e for _, _, e in rows if np.isfinite(e.added)]
    print(
        f"{sum(e.added <= args.limit for e in judged)} of {len(judged)} outages within {args.limit:g} m"
        f"{f' ({len(rows) - len(judged)} met before the {args.target} was initialised)' if len(judged) < len(rows) else ''}"
    )


if __name__ == "__main__":
    main()
