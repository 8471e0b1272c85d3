"""Fusion through GPS outages: the fused error under bridges and through the receiver's wrong
smoothed estimate after them, against gps_only and hdop_switch, with exact truth.

The real stack (world, sim.Trajectory, sim.HDL32E, sim.GnssReceiver, matcher --matcher) is
simulated once over the whole route and recorded (benchmarks/stream_record.py; reused from --out);
gps_only, hdop_switch, ekf and pf at their defaults are replayed over all of it, so that each
meets an outage with the state the route gave it. Every stretch without a measured fix (GGA 0 or 6)
of at least --min-outage s is an outage; the table gives each estimator's horizontal error (max and
mean) during it and in the --after s once fixes return, then the whole route's median and p95. A
PNG per outage goes to --out.

    .venv/bin/python benchmarks/outages.py [--world charles_river] [--matcher gicp]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
import fusion  # noqa: E402
from stream_record import add_recording_args, load_or_record, replay  # noqa: E402

NAMES = ("gps_only", "hdop_switch", "ekf", "pf")


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


def run_outages(args) -> None:
    rec = load_or_record(Path(args.out), args.world, args.matcher, args.seed, 0.0, None)
    run = replay(rec, {n: fusion.create(n, matcher=args.matcher) for n in NAMES})
    quality = np.array([f.quality for f in run["fix"]])
    windows = outage_windows(run["fix_stamp"], quality, args.min_outage)
    print(f"{args.world}, matcher {args.matcher}, seed {args.seed}: {len(windows)} outage(s) >= {args.min_outage} s: "
          + ", ".join(f"{a:.1f}-{b:.1f}" for a, b in windows))
    t = run["scan_stamp"]
    error = {n: np.hypot(*(run["estimate"][n][:, :2] - run["truth"][:, :2]).T) for n in NAMES}
    fix_error = np.array([np.hypot(*f.truth.error[:2]) for f in run["fix"]])
    print(f"{'outage':>13} {'estimator':>12} {'out max':>8} {'out mean':>8} {'after max':>9} {'after mean':>10}")
    for k, (a, b) in enumerate(windows):
        out, after = (t >= a) & (t < b), (t >= b) & (t < b + args.after)
        for n in NAMES:
            e = error[n]
            print(f"{a:6.1f}-{b:6.1f} {n:>12} {np.nanmax(e[out]):8.2f} {np.nanmean(e[out]):8.2f} "
                  f"{np.nanmax(e[after]):9.2f} {np.nanmean(e[after]):10.2f}")
        span = (t >= a - args.before) & (t < b + args.after)
        fspan = (run["fix_stamp"] >= a - args.before) & (run["fix_stamp"] < b + args.after)
        plot_errors(t[span], {n: error[n][span] for n in NAMES}, run["fix_stamp"][fspan], fix_error[fspan], (a, b),
                    Path(args.out) / f"fusion_outage_{args.world}_{k}.png", f"{args.world}: outage {a:.1f}-{b:.1f} s ({args.matcher})")
    print(f"\nwhole route ({len(t)} scans): horizontal error at scan times, m")
    for n in NAMES:
        print(f"{n:>12} median {np.nanmedian(error[n]):6.2f}  p95 {np.nanpercentile(error[n], 95):6.2f}  max {np.nanmax(error[n]):6.2f}")


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
    parser.add_argument("--min-outage", type=float, default=2.0)
    parser.add_argument("--before", type=float, default=40.0)
    parser.add_argument("--after", type=float, default=30.0)
    run_outages(parser.parse_args())


if __name__ == "__main__":
    main()
