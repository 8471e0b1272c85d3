"""GPS integrity monitors scored against the exact truth on a simulated route.

The real stack (worlds.load(--world), sim.Trajectory, sim.HDL32E, sim.GnssReceiver, matcher
--matcher) is simulated once and recorded (benchmarks/stream_record.py; reused from --out when the
same settings were recorded before); every estimator is then replayed over the recording: the ekf
under each monitor (hdop, nis, consistency, cn0, combined = nis + consistency, combined_cn0 =
consistency + cn0, and nis + consistency + cn0), plus pf,
gps_only and hdop_switch.

A measured fix (GGA 1) is faulty when its true horizontal error exceeds a threshold; tables for
each of --fault-m (default 5 m, the issue's, and 10 m). Per monitor: precision, recall and
false-alarm rate at its default gate; recall at <= 5 % false alarms from its ROC (thresholding
its statistic; NaN = never flagged) and the hdop monitor's recall at that same false-alarm rate;
the area under the ROC. Then recall per fault cause, from the truth: 'nlos' (the fix used a
satellite received only by reflection), 'outage' (within --after-outage-s of an epoch without a
measured position), 'other' (neither: the receiver's slowly varying range errors through the
geometry); at the default gate and at the 5 % false-alarm threshold. ROC curves go to --out.

    .venv/bin/python benchmarks/monitors.py [--world charles_river] [--matcher gicp] [--t-end 600]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy.stats import rankdata

sys.path.insert(0, str(Path(__file__).resolve().parent))
from stream_record import add_recording_args, load_or_record, parse_settings, replay

import fusion
from fusion.observation import POSITION_QUALITIES

MONITORS = {
    "hdop": {"monitor": "hdop"},
    "nis": {"monitor": "nis"},
    "consistency": {"monitor": "consistency"},
    "cn0": {"monitor": "cn0"},
    "combined": {"monitor": "combined", "monitor_params": {"members": ["nis", "consistency"]}},
    "combined_cn0": {"monitor": "combined_cn0"},
    "nis+cons+cn0": {"monitor": "combined", "monitor_params": {"members": ["nis", "consistency", "cn0"]}},
}
CAUSES = ("nlos", "outage", "other")


def roc(statistic: np.ndarray, faulty: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """False-alarm rate, recall and threshold for every distinct threshold on the statistic (flag when >=; NaN never flagged)."""
    s = np.where(np.isnan(statistic), -np.inf, statistic)
    order = np.argsort(-s, kind="stable")
    s_sorted, f_sorted = s[order], faulty[order]
    last = np.r_[np.nonzero(s_sorted[1:] != s_sorted[:-1])[0], len(s) - 1]  # last index of each run of equal scores
    tp, fp = np.cumsum(f_sorted)[last], np.cumsum(~f_sorted)[last]
    n_pos, n_neg = max(int(faulty.sum()), 1), max(int((~faulty).sum()), 1)
    keep = np.isfinite(s_sorted[last])  # -inf (NaN) is never flagged
    return np.r_[0.0, fp[keep] / n_neg], np.r_[0.0, tp[keep] / n_pos], np.r_[np.inf, s_sorted[last][keep]]


def at_fa(fa: np.ndarray, rec: np.ndarray, thr: np.ndarray, max_fa: float) -> tuple[float, float, float]:
    """Best recall with false alarms <= max_fa: (recall, its false-alarm rate, its threshold)."""
    ok = np.nonzero(fa <= max_fa + 1e-12)[0]
    i = ok[np.argmax(rec[ok])]
    return float(rec[i]), float(fa[i]), float(thr[i])


def auc(statistic: np.ndarray, faulty: np.ndarray) -> float:
    """Probability that a faulty fix scores above a clean one (ties half; NaN lowest)."""
    if faulty.all() or not faulty.any():
        return float("nan")
    r = rankdata(np.where(np.isnan(statistic), -np.inf, statistic))
    n_pos, n_neg = faulty.sum(), (~faulty).sum()
    return float((r[faulty].sum() - n_pos * (n_pos + 1) / 2) / (n_pos * n_neg))


def causes(fixes: list, after_outage_s: float) -> np.ndarray:
    """Per fix: 'nlos' if it used a satellite the truth says is NLOS, else 'outage' if within
    after_outage_s of an epoch without a measured position, else 'other'."""
    out, last_gap = [], -np.inf
    for fix in fixes:
        if fix.quality not in POSITION_QUALITIES:
            last_gap = fix.stamp
        nlos_prn = {(s.system, s.prn) for s in (fix.truth.sats if fix.truth is not None else ()) if s.nlos}
        if any(s.used and (s.system, s.prn) in nlos_prn for s in fix.sats):
            out.append("nlos")
        elif fix.quality in POSITION_QUALITIES and fix.stamp - last_gap <= after_outage_s:
            out.append("outage")
        else:
            out.append("other")
    return np.asarray(out)


def table(run: dict, names: list[str], measured: np.ndarray, faulty: np.ndarray, label: str, cause: np.ndarray, ax) -> None:
    """Print the monitors' table for one fault definition and draw their ROC on ax."""
    print(
        f"\nfaulty: {label}: {faulty.sum()} of {len(faulty)} measured fixes ({faulty.mean():.1%}); "
        + ", ".join(f"{c} {int((faulty & (cause == c)).sum())}" for c in CAUSES)
        + " (all fixes: "
        + ", ".join(f"{c} {int((cause == c).sum())}" for c in CAUSES)
        + ")"
    )
    print(
        f"{'monitor':>13} {'prec':>6} {'recall':>6} {'FA':>6} | {'rec@5%FA':>8} {'(FA)':>6} {'hdop@FA':>7} {'AUC':>5} | "
        + " ".join(f"{c + '@gate':>11}" for c in CAUSES)
        + " | "
        + " ".join(f"{c + '@5%':>10}" for c in CAUSES)
    )
    fa_h, rec_h, _ = roc(run["statistic"]["hdop"][measured], faulty)
    best = ("", -1.0, 0.0)
    for name in names:
        flagged = ~run["trusted"][name][measured]
        stat = run["statistic"][name][measured]
        tp = int((flagged & faulty).sum())
        precision = tp / max(int(flagged.sum()), 1)
        recall = tp / max(int(faulty.sum()), 1)
        false_alarm = float((flagged & ~faulty).sum()) / max(int((~faulty).sum()), 1)
        fa, rec, thr = roc(stat, faulty)
        r5, fa5, t5 = at_fa(fa, rec, thr, 0.05)
        hdop_same = at_fa(fa_h, rec_h, np.zeros_like(fa_h), fa5)[0]
        flagged5 = np.where(np.isnan(stat), -np.inf, stat) >= t5
        per_gate = [_share(flagged, faulty & (cause == c)) for c in CAUSES]
        per_5 = [_share(flagged5, faulty & (cause == c)) for c in CAUSES]
        print(
            f"{name:>13} {precision:6.3f} {recall:6.3f} {false_alarm:6.3f} | {r5:8.3f} {fa5:6.3f} {hdop_same:7.3f} {auc(stat, faulty):5.3f} | "
            + " ".join(f"{v:>11}" for v in per_gate)
            + " | "
            + " ".join(f"{v:>10}" for v in per_5)
        )
        ax.plot(fa, rec, label=name)
        best = max(best, (name, r5, hdop_same), key=lambda b: b[1])
    met = "met" if best[1] >= 0.9 else "not met"
    print(f"target (>= 90% recall at <= 5% false alarms): {met}; best {best[0]} {best[1]:.3f} against hdop {best[2]:.3f} at the same rate")
    ax.plot([0, 1], [0, 1], "k:", lw=0.8)
    ax.axvline(0.05, color="0.6", lw=0.8)
    ax.set_xlabel("false-alarm rate")
    ax.set_ylabel(f"recall (faulty: {label})")
    ax.legend(fontsize=7)


def _share(flagged: np.ndarray, group: np.ndarray) -> str:
    """Recall within a group, as 'r.rrr' (or '-' for an empty group)."""
    return f"{(flagged & group).sum() / group.sum():.3f}" if group.any() else "-"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_recording_args(parser)
    parser.add_argument("--t-start", type=float, default=0.0)
    parser.add_argument("--t-end", type=float, default=None)
    parser.add_argument("--fault-m", type=float, nargs="+", default=[5.0, 10.0])
    parser.add_argument("--after-outage-s", type=float, default=10.0)
    parser.add_argument(
        "--monitors",
        nargs="+",
        default=list(MONITORS),
        choices=list(MONITORS),
        help="ekf monitor variants to score (hdop is always run: the baseline)",
    )
    parser.add_argument("--no-estimators", action="store_true", help="skip pf, gps_only and hdop_switch")
    args = parser.parse_args()
    names = ["hdop"] + [m for m in args.monitors if m != "hdop"]
    out = Path(args.out)
    rec = load_or_record(out, args.world, args.matcher, args.seed, args.t_start, args.t_end, parse_settings(args.settings))
    estimators = {n: fusion.create("ekf", matcher=args.matcher, **MONITORS[n]) for n in names}
    if not args.no_estimators:
        estimators["pf"] = fusion.create("pf", matcher=args.matcher)
        estimators["gps_only"] = fusion.create("gps_only")
        estimators["hdop_switch"] = fusion.create("hdop_switch", matcher=args.matcher)
    start = time.perf_counter()
    run = replay(rec, estimators)
    quality = np.array([f.quality for f in run["fix"]])
    measured = np.isin(quality, sorted(POSITION_QUALITIES))
    truth = [f.truth for f in np.asarray(run["fix"], dtype=object)[measured]]
    error = np.array([np.hypot(*t.error[:2]) for t in truth])
    added = np.array([np.hypot(*(t.error - t.open_sky_error)[:2]) for t in truth])
    cause = causes(run["fix"], args.after_outage_s)[measured]
    n_scans = len(run["scan_stamp"])
    ok = np.mean([item[2].ok for item in rec.items if item[0] == "scan"])
    print(
        f"{args.world} [{rec.t_start:.0f}, {rec.t_end:.0f}] s, matcher {args.matcher} (ok {ok:.1%} of {n_scans} scans), seed {args.seed}: "
        f"recorded in {rec.wall_s:.0f} s wall, {len(estimators)} estimators replayed in {time.perf_counter() - start:.0f} s; "
        f"{measured.sum()} measured fixes of {len(quality)}"
    )
    nominal = np.array([np.hypot(*t.open_sky_error[:2]) for t in truth])
    print(
        f"the same receiver under an open sky (nominal error, unobservable to odometry): median {np.median(nominal):.2f} m, "
        f"p95 {np.percentile(nominal, 95):.2f} m; " + ", ".join(f"over {m:g} m: {np.mean(nominal > m):.1%} of fixes" for m in args.fault_m)
    )
    definitions = [(f"error > {m:g} m", error > m) for m in args.fault_m]
    definitions += [(f"environment adds > {m:g} m", added > m) for m in args.fault_m]
    fig, axes = plt.subplots(2, len(args.fault_m), figsize=(5.5 * len(args.fault_m), 10), squeeze=False)
    for (label, faulty), ax in zip(definitions, axes.ravel()):
        table(run, names, measured, faulty, label, cause, ax)
        ax.set_title(f"{args.world}: {label}")
    fig.tight_layout()
    out.mkdir(parents=True, exist_ok=True)
    png = out / f"fusion_roc_{args.world}.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)
    print(f"\n{'estimator':>13} {'median':>7} {'p95':>7} {'max':>7}  (horizontal error at scan times, m)")
    for n in estimators:
        e = np.hypot(*(run["estimate"][n][:, :2] - run["truth"][:, :2]).T)
        print(f"{n:>13} {np.nanmedian(e):7.2f} {np.nanpercentile(e, 95):7.2f} {np.nanmax(e):7.2f}")
    print(f"ROC: {png}")


if __name__ == "__main__":
    main()
