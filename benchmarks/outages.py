"""Fusion through GPS outages: the fused error under bridges and through the receiver's wrong
smoothed estimate after them, against gps_only and hdop_switch, with exact truth.

A receiver-only pass over the route finds every stretch without a measured fix (GGA 0 or 6) of at
least --min-outage s; each is driven from --before s ahead to --after s past it with LiDAR, the
matcher and the estimators (gps_only, hdop_switch, ekf, pf at their defaults). The table gives each
estimator's horizontal error (max and mean) during the outage and in the --after s once fixes
return; a PNG per outage goes to --out.

    .venv/bin/python benchmarks/outages.py [--world charles_river] [--matcher gicp]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import fusion  # noqa: E402
import matcher  # noqa: E402
import sim  # noqa: E402
import worlds  # noqa: E402
from scenarios.stream import Track, drive  # noqa: E402
from sim.gnss import GnssReceiver  # noqa: E402


def outage_windows(world, trajectory, seed: int, min_s: float) -> list[tuple[float, float]]:
    """[start, end) of every stretch without a measured fix lasting at least min_s (receiver only)."""
    receiver = GnssReceiver(seed=seed)
    windows, start = [], None
    for t in receiver.epochs(trajectory.duration):
        measured = receiver.fix(world, trajectory, t).quality in (1, 2, 4, 5)
        if not measured and start is None:
            start = t
        elif measured and start is not None:
            if t - start >= min_s:
                windows.append((float(start), float(t)))
            start = None
    return windows


def run_outages(args) -> None:
    world = worlds.load(args.world)
    trajectory = sim.Trajectory(world, seed=args.seed)
    windows = outage_windows(world, trajectory, args.seed, args.min_outage)
    print(f"{args.world}: {len(windows)} outage(s) >= {args.min_outage} s: " + ", ".join(f"{a:.1f}-{b:.1f}" for a, b in windows))
    names = ("gps_only", "hdop_switch", "ekf", "pf")
    header = f"{'outage':>13} {'estimator':>12} {'out max':>8} {'out mean':>8} {'after max':>9} {'after mean':>10}"
    rows = []
    for k, (a, b) in enumerate(windows):
        t0, t1 = max(0.0, a - args.before), min(trajectory.duration, b + args.after)
        estimators = {n: fusion.create(n, matcher=args.matcher) for n in names}
        track = drive(world, trajectory, sim.HDL32E(seed=args.seed), GnssReceiver(seed=args.seed),
                      {args.matcher: matcher.create(args.matcher)}, estimators, t0, t1)
        out = (track.scan_stamp >= a) & (track.scan_stamp < b)
        after = (track.scan_stamp >= b) & (track.scan_stamp < b + args.after)
        for n in names:
            e = track.error(n)
            rows.append(f"{a:6.1f}-{b:6.1f} {n:>12} {np.nanmax(e[out]):8.2f} {np.nanmean(e[out]):8.2f} "
                        f"{np.nanmax(e[after]):9.2f} {np.nanmean(e[after]):10.2f}")
        plot_errors(track, names, (a, b), Path(args.out) / f"fusion_outage_{args.world}_{k}.png",
                    f"{args.world}: outage {a:.1f}-{b:.1f} s ({args.matcher})")
    print(header)
    print("\n".join(rows))


def plot_errors(track: Track, names, window, path: Path, title: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, ax = plt.subplots(figsize=(10, 4.5))
    for n in names:
        ax.plot(track.scan_stamp, track.error(n), label=n, lw=1.2)
    ax.plot(track.fix_stamp, track.fix_error, "k.", ms=2, label="fix true error")
    ax.axvspan(*window, color="0.85", label="no measured fix")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("horizontal error (m)")
    ax.set_ylim(0, min(30.0, max(5.0, 1.1 * float(np.nanmax([np.nanmax(track.error(n)) for n in names])))))
    ax.set_title(title)
    ax.legend(ncol=3, fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--world", default="charles_river")
    parser.add_argument("--matcher", default="gicp")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="benchmarks/out")
    parser.add_argument("--min-outage", type=float, default=2.0)
    parser.add_argument("--before", type=float, default=40.0)
    parser.add_argument("--after", type=float, default=60.0)
    run_outages(parser.parse_args())


if __name__ == "__main__":
    main()
