"""GPS integrity monitors scored against the exact truth on a simulated route.

One drive over the route (or [--t-start, --t-end]) with the ekf under each monitor (hdop, nis,
consistency, combined), plus pf, gps_only and hdop_switch. A measured fix (GGA 1) is faulty when
its true horizontal error exceeds --fault-m (default 5 m). The table: precision, recall and
false-alarm rate at each monitor's default gate; the recall reached at <= 5 % false alarms by
thresholding its statistic (ROC); and the hdop monitor's recall at that same false-alarm rate.
The ROC curves go to --out as a PNG; the estimators' horizontal errors are printed too.

    .venv/bin/python benchmarks/monitors.py [--world charles_river] [--matcher gicp] [--t-end 600]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import fusion  # noqa: E402
import matcher  # noqa: E402
import sim  # noqa: E402
import worlds  # noqa: E402
from scenarios.stream import drive  # noqa: E402
from sim.gnss import GnssReceiver  # noqa: E402

MONITORS = ("hdop", "nis", "consistency", "combined")


def progress(total_s: float, every_s: float = 60.0):
    """An on_event callback printing sim time now and then."""
    state = {"next": every_s, "t0": time.perf_counter()}

    def tick(event) -> None:
        if event.stamp >= state["next"]:
            rate = event.stamp / (time.perf_counter() - state["t0"])
            print(f"  ... {event.stamp:7.1f} / {total_s:.0f} s simulated ({rate:.2f}x real time)", flush=True)
            state["next"] += every_s

    return tick


def roc(statistic: np.ndarray, faulty: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """False-alarm rate and recall for every threshold on the statistic (NaN counts as never flagged)."""
    s = np.where(np.isnan(statistic), -np.inf, statistic)
    thresholds = np.r_[np.inf, np.unique(s)[::-1]]
    fa = np.array([(s[~faulty] >= t).mean() if (~faulty).any() else 0.0 for t in thresholds])
    rec = np.array([(s[faulty] >= t).mean() if faulty.any() else 0.0 for t in thresholds])
    return fa, rec


def recall_at(fa: np.ndarray, rec: np.ndarray, max_fa: float) -> float:
    ok = fa <= max_fa + 1e-12
    return float(rec[ok].max()) if ok.any() else 0.0


def run_monitors(args) -> None:
    world = worlds.load(args.world)
    trajectory = sim.Trajectory(world, seed=args.seed)
    t_end = trajectory.duration if args.t_end is None else min(args.t_end, trajectory.duration)
    estimators = {m: fusion.create("ekf", matcher=args.matcher, monitor=m) for m in MONITORS}
    estimators["pf"] = fusion.create("pf", matcher=args.matcher)
    estimators["gps_only"] = fusion.create("gps_only")
    estimators["hdop_switch"] = fusion.create("hdop_switch", matcher=args.matcher)
    start = time.perf_counter()
    track = drive(world, trajectory, sim.HDL32E(seed=args.seed), GnssReceiver(seed=args.seed),
                  {args.matcher: matcher.create(args.matcher)}, estimators, args.t_start, t_end,
                  on_event=progress(t_end, 120.0))
    wall = time.perf_counter() - start
    measured = track.fix_quality == 1
    faulty = track.fix_error[measured] > args.fault_m
    print(f"{args.world} [{args.t_start:.0f}, {t_end:.0f}] s with {args.matcher}: {wall:.0f} s wall; "
          f"{measured.sum()} measured fixes, {faulty.sum()} faulty (> {args.fault_m:g} m, {faulty.mean():.1%}); "
          f"matcher ok {track.match_ok[args.matcher].mean():.1%}")
    print(f"{'monitor':>12} {'precision':>9} {'recall':>7} {'false-al':>8} {'recall@5%FA':>11} {'hdop@same':>9}")
    fa_h, rec_h = roc(track.statistic["hdop"][measured], faulty)
    fig, ax = plt.subplots(figsize=(5.5, 5))
    for m in MONITORS:
        flagged = ~track.trusted[m][measured]
        tp = int((flagged & faulty).sum())
        precision = tp / max(int(flagged.sum()), 1)
        recall = tp / max(int(faulty.sum()), 1)
        false_alarm = float((flagged & ~faulty).sum()) / max(int((~faulty).sum()), 1)
        fa, rec = roc(track.statistic[m][measured], faulty)
        r5 = recall_at(fa, rec, 0.05)
        fa5 = float(fa[fa <= 0.05 + 1e-12].max()) if (fa <= 0.05 + 1e-12).any() else 0.0
        print(f"{m:>12} {precision:9.3f} {recall:7.3f} {false_alarm:8.3f} {r5:11.3f} {recall_at(fa_h, rec_h, fa5):9.3f}")
        ax.plot(fa, rec, label=m)
    ax.plot([0, 1], [0, 1], "k:", lw=0.8)
    ax.axvline(0.05, color="0.6", lw=0.8)
    ax.set_xlabel("false-alarm rate")
    ax.set_ylabel(f"recall (faulty: error > {args.fault_m:g} m)")
    ax.set_title(f"GPS integrity monitors, {args.world}")
    ax.legend()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out / f"fusion_roc_{args.world}.png", dpi=110)
    plt.close(fig)
    print(f"{'estimator':>12} {'median':>7} {'p95':>7} {'max':>7}  (horizontal error at scan times, m)")
    for n in estimators:
        e = track.error(n)
        print(f"{n:>12} {np.nanmedian(e):7.2f} {np.nanpercentile(e, 95):7.2f} {np.nanmax(e):7.2f}")
    print(f"ROC: {out / f'fusion_roc_{args.world}.png'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--world", default="charles_river")
    parser.add_argument("--matcher", default="gicp")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="benchmarks/out")
    parser.add_argument("--t-start", type=float, default=0.0)
    parser.add_argument("--t-end", type=float, default=None)
    parser.add_argument("--fault-m", type=float, default=5.0)
    run_monitors(parser.parse_args())


if __name__ == "__main__":
    main()
