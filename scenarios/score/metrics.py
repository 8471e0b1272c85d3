"""Every metric of a run, from its RunRecord and the exact truth; nested as metrics.json.

Errors are horizontal (x, y in the world ENU frame) at scan times. APE statistics: rmse, mean,
median, p95, max. RPE per d metres of true travel: for each scan i and the first scan j at least d
metres further, the error of the estimated displacement expressed in the estimate's own frame at i
against the true one in the true frame at i (as evo's RPE with a distance delta). Matchers' odometry
is chained from the true start pose; `ape_aligned` first removes the best-fit rigid motion (SE(2),
as evo's --align). Monitors: a measured fix is faulty when its true error exceeds 5 m (`error_5m`)
or when what the environment added to it exceeds 5 m (`added_5m`, what integrity monitoring can see).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fnmatch import fnmatchcase

import numpy as np

from riverbench.angles import wrap_angle
from scenarios.score import windows as win
from scenarios.score.record import FixTable, HeadingTable, RunRecord

RPE_DISTANCES_M = (10.0, 100.0)
FAULT_M = 5.0
FALSE_ALARM_BUDGET = 0.05


@dataclass(frozen=True)
class Family:
    """A family of metrics judged alike against a baseline: which way is better and what change is too small to call.

    A change is called when the median over seeds of the paired change (now - baseline, same seed) exceeds
    max(abs_tol, rel_tol x |baseline median|, the seeds' own noise) in the worse or better direction
    (scenarios.score.regression). `better` "none" marks what describes the scenario rather than the code under test
    (GPS the simulated receiver gave, window counts, point counts): any change is reported, none is a regression.
    """

    name: str
    patterns: tuple[str, ...]
    better: str  # "lower", "higher" or "none"
    abs_tol: float = 0.0
    rel_tol: float = 0.0
    any_seed: bool = False  # a 0/1 outcome (a crash, a collision): one seed worse is a regression
    wall_clock: bool = False  # depends on the machine's load: reported, never an exit-1 regression


FAMILIES: tuple[Family, ...] = (
    Family(
        "wall clock",
        ("run.wall_s", "matchers.*.ms.*", "*.external.wall_s", "*.external.cpu_s", "*.external.recording_s"),
        "lower",
        rel_tol=0.5,
        wall_clock=True,
    ),
    Family("speed", ("run.realtime_factor", "matchers.*.hz"), "higher", rel_tol=0.33, wall_clock=True),
    Family("memory", ("run.peak_rss_mb", "*.external.peak_rss_mb"), "lower", rel_tol=0.25, wall_clock=True),
    Family("component failures", ("estimators.*.failed", "matchers.*.failed"), "lower", any_seed=True),
    Family("collisions", ("vessel.collisions",), "lower", any_seed=True),
    Family("completion", ("vessel.completed",), "higher", any_seed=True),
    Family(
        "scenario",
        (
            "run.*",
            "gps.*",
            "estimators.*.windows.*.count",
            "estimators.*.windows.*.seconds",
            "estimators.*.monitor.*.faulty",
            "*.rpe_*m.pairs",
            "*.failed_at",
            "matchers.*.gated",
            "matchers.*.points.*",
            "vessel.clearance_threshold_m",
            "estimators.*.integrity.alert_limit_m",
            "vessel.distance_m",
            "vessel.collision_t",
            "vessel.min_clearance_t",
            "*.source.poses",
            "*.external.poses",
            "*.external.exit_code",
            "*.external.recording_cached",
        ),
        "none",
    ),
    Family(
        "position error",
        (
            "*.ape.*",
            "*.ape_aligned.*",
            "*.rpe_*m.rmse",
            "*.rpe_*m.mean",
            "*.rpe_*m.median",
            "*.rpe_*m.p95",
            "*.rpe_*m.max",
            "estimators.*.windows.*.max_error",
            "estimators.*.windows.*.exit_error",
            "estimators.*.windows.*.added",
            "vessel.cross_track.*",
        ),
        "lower",
        abs_tol=0.05,
        rel_tol=0.10,
    ),
    Family("drift per distance", ("*.rpe_*m.percent",), "lower", abs_tol=0.05, rel_tol=0.10),
    Family("heading error", ("*.yaw.*",), "lower", abs_tol=0.1, rel_tol=0.10),
    Family("compass disturbance", ("compass.disturbed", "compass.disturbed_s", "estimators.*.compass.used"), "none"),
    Family("disturbed compass used", ("estimators.*.compass.disturbed_used",), "lower", abs_tol=0.02),
    Family("recovery time", ("estimators.*.windows.*.recover_s", "estimators.*.windows.*.settle_s"), "lower", abs_tol=0.5, rel_tol=0.20),
    Family("recovered share", ("estimators.*.windows.*.recovered", "estimators.*.windows.*.settled"), "higher", abs_tol=0.01),
    Family("availability", ("estimators.*.available", "estimators.*.integrity.available", "*.coverage"), "higher", abs_tol=0.005),
    Family("protection level", ("estimators.*.integrity.hpl.*",), "none"),
    Family("misleading information", ("estimators.*.integrity.misleading",), "lower", abs_tol=0.005),
    Family("misleading epochs", ("estimators.*.integrity.misleading_epochs", "estimators.*.integrity.hazardous_epochs"), "lower", abs_tol=2.0),
    Family(
        "fault detection",
        ("estimators.*.monitor.*.recall", "estimators.*.monitor.*.recall_at_5pct_fa", "estimators.*.monitor.*.precision"),
        "higher",
        abs_tol=0.03,
    ),
    Family("false alarms", ("estimators.*.monitor.*.false_alarm_rate",), "lower", abs_tol=0.01, rel_tol=0.10),
    Family("matching success", ("matchers.*.success",), "higher", abs_tol=0.01),
    Family("degenerate matches", ("matchers.*.degenerate",), "lower", abs_tol=0.02),
    Family("clearance", ("vessel.min_clearance_m",), "higher", abs_tol=0.2, rel_tol=0.10),
    Family("time near structures", ("vessel.time_below_threshold_s",), "lower", abs_tol=1.0, rel_tol=0.20),
)
"""Every number of metrics.json, by family (first match of its dotted path wins); directions declared once, here."""
UNCLASSIFIED = Family("unclassified", ("*",), "none")


def family_of(path: str) -> Family:
    """The family of a metric's dotted path (UNCLASSIFIED, never a regression, when none matches)."""
    return next((f for f in FAMILIES if any(fnmatchcase(path, p) for p in f.patterns)), UNCLASSIFIED)


def stats(values: np.ndarray) -> dict:
    """rmse, mean, median, p95, max over the finite values (NaN when there are none)."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if not len(v):
        return {k: math.nan for k in ("rmse", "mean", "median", "p95", "max")}
    return {
        "rmse": float(np.sqrt(np.mean(v**2))),
        "mean": float(v.mean()),
        "median": float(np.median(v)),
        "p95": float(np.percentile(v, 95)),
        "max": float(v.max()),
    }


def yaw_of(poses: np.ndarray) -> np.ndarray:
    return np.arctan2(poses[:, 1, 0], poses[:, 0, 0])


def horizontal_error(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    return np.hypot(estimate[:, 0, 3] - truth[:, 0, 3], estimate[:, 1, 3] - truth[:, 1, 3])


def yaw_error_deg(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    d = yaw_of(estimate) - yaw_of(truth)
    return np.degrees(np.abs(wrap_angle(d)))


def travelled(truth: np.ndarray) -> np.ndarray:
    """(N,) true horizontal distance travelled since the first scan."""
    step = np.hypot(np.diff(truth[:, 0, 3]), np.diff(truth[:, 1, 3]))
    return np.r_[0.0, np.cumsum(step)]


def rpe(estimate: np.ndarray, truth: np.ndarray, distance_m: float) -> dict:
    """Relative translation error per `distance_m` of true travel (stats in metres, plus percent of the distance)."""
    s = travelled(truth)
    i = np.arange(len(s))
    j = np.searchsorted(s, s + distance_m)
    keep = j < len(s)
    i, j = i[keep], j[keep]
    errors = np.full(len(i), math.nan)
    if len(i):
        errors = np.linalg.norm(_relative_xy(estimate, i, j) - _relative_xy(truth, i, j), axis=1)
    out = stats(errors)
    out["pairs"] = int(np.isfinite(errors).sum())
    out["percent"] = 100.0 * out["mean"] / distance_m if math.isfinite(out["mean"]) else math.nan
    return out


def _relative_xy(poses: np.ndarray, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """(K, 2) position of pose j in the planar (x, y, yaw) frame of pose i."""
    yaw = yaw_of(poses[i])
    d = poses[j, :2, 3] - poses[i, :2, 3]
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)


def align_se2(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """estimate (N, 4, 4) moved by the rigid planar motion that best fits its positions to the truth's."""
    ok = np.isfinite(estimate[:, :2, 3]).all(axis=1)
    if ok.sum() < 2:
        return estimate
    p, q = estimate[ok, :2, 3], truth[ok, :2, 3]
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    h = (p - pc).T @ (q - qc)
    angle = math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
    c, s = math.cos(angle), math.sin(angle)
    motion = np.eye(4)
    motion[:2, :2] = [[c, -s], [s, c]]
    motion[:2, 3] = qc - motion[:2, :2] @ pc
    return motion @ estimate


def align_se3(estimate: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """estimate (N, 4, 4) moved by the rigid motion that best fits its 3-D positions to the truth's (Umeyama's least squares
    without scale, as evo's `-a`): for odometry whose frame is unknown, tilted or not (the poses may be NaN where missing)."""
    ok = np.isfinite(estimate[:, :3, 3]).all(axis=1) & np.isfinite(truth[:, :3, 3]).all(axis=1)
    if ok.sum() < 3:
        return estimate
    p, q = estimate[ok, :3, 3], truth[ok, :3, 3]
    pc, qc = p.mean(axis=0), q.mean(axis=0)
    u, _, vt = np.linalg.svd((q - qc).T @ (p - pc))
    flip = np.diag([1.0, 1.0, np.sign(np.linalg.det(u) * np.linalg.det(vt)) or 1.0])
    motion = np.eye(4)
    motion[:3, :3] = u @ flip @ vt
    motion[:3, 3] = qc - motion[:3, :3] @ pc
    return motion @ estimate


ALERT_LIMIT_M = 10.0
"""The default horizontal alert limit (scenarios.spec.scenario.IntegrityConfig)."""


def estimate_metrics(estimate: np.ndarray, truth: np.ndarray, scan_t: np.ndarray, windows: list[win.Window]) -> dict:
    """What an estimate in the world (N, 4, 4) at the scan times is scored by against the truth there: available (share of
    scans with a pose), ape, rpe per distance, yaw and the GPS-degradation windows (what every estimator gets, built in or
    scored in afterwards by scenarios.pipeline.rescore)."""
    error = horizontal_error(estimate, truth)
    yaw_error = yaw_error_deg(estimate, truth)
    return {
        "available": float(np.isfinite(error).mean()) if len(error) else math.nan,
        "ape": stats(error),
        **{f"rpe_{d:g}m": rpe(estimate, truth, d) for d in RPE_DISTANCES_M},
        "yaw": stats(yaw_error),
        "windows": window_metrics(windows, scan_t, error, yaw_error),
    }


def estimator_metrics(rec: RunRecord, eid: str, windows: list[win.Window], alert_limit_m: float = ALERT_LIMIT_M) -> dict:
    est, truth = rec.estimates[eid], rec.truth
    error = horizontal_error(est, truth)
    out = {
        **estimate_metrics(est, truth, rec.scan_t, windows),
        "monitor": monitor_metrics(rec.fixes, eid),
        "integrity": integrity_metrics(error, rec.protection.get(eid, np.full(len(error), math.nan)), alert_limit_m),
    }
    failed = [f for f in rec.failures if f["component"] == "estimator" and f["id"] == eid]
    out["failed"] = bool(failed)
    if failed:
        out["failed_at"] = failed[0]["stamp"]
    return out


def integrity_metrics(error: np.ndarray, level: np.ndarray, alert_limit_m: float) -> dict:
    """The standard integrity figures of an estimator's horizontal protection level (HPL) over the scans where it had both
    an estimate and a level: `misleading` the share of epochs whose error exceeded HPL (and `misleading_epochs` their
    count), `hazardous_epochs` those whose error exceeded the alert limit while HPL was below it, `available` the share
    of the run's scans with HPL below the alert limit (a scan without an estimate or a level is not available), and
    `hpl` its distribution (NaN throughout for an estimator that reports no level)."""
    both = np.isfinite(error) & np.isfinite(level)
    e, pl = error[both], level[both]
    if not len(e):
        unmeasured = dict.fromkeys(("misleading", "misleading_epochs", "hazardous_epochs", "available"), math.nan)
        return {"alert_limit_m": alert_limit_m, "hpl": stats(e), **unmeasured}
    return {
        "alert_limit_m": alert_limit_m,
        "hpl": stats(pl),
        "misleading": float(np.mean(e > pl)),
        "misleading_epochs": int(np.sum(e > pl)),
        "hazardous_epochs": int(np.sum((e > alert_limit_m) & (pl < alert_limit_m))),
        "available": float(np.sum(pl < alert_limit_m) / len(error)),
    }


def window_metrics(windows: list[win.Window], t: np.ndarray, error: np.ndarray, yaw_error: np.ndarray | None = None) -> dict:
    """Per kind: count, total seconds, and the worst max error, exit error, added error and recovery
    time over its windows; `recovered` is the share of windows after which the error came back
    (recover_s is the worst over those that did); `settled` the share after which it came within SETTLED_M of the truth
    to stay (SETTLED_FOR_S, or until the next window; settle_s the worst time that took over those that did); with
    `yaw_error` (deg), `yaw`: the heading error's p95 and max over the scans inside its windows, where a filter that
    trusted odometry or a disturbed compass shows its heading drift."""
    out = {}
    for kind in win.KINDS:
        mine = [w for w in windows if w.kind == kind]
        passages = [win.passage(w, t, error, win.next_start(w, windows)) for w in mine]
        worst = lambda key, passages=passages: _nanmax([getattr(p, key) for p in passages])
        recovered = [math.isfinite(p.recover_s) for p in passages]
        out[kind] = {
            "count": len(mine),
            "seconds": float(sum(w.duration for w in mine)),
            "max_error": worst("max_error"),
            "exit_error": worst("exit_error"),
            "added": worst("added"),
            "recover_s": worst("recover_s"),
            "recovered": float(np.mean(recovered)) if recovered else math.nan,
            "settle_s": worst("settle_s"),
            "settled": float(np.mean([math.isfinite(p.settle_s) for p in passages])) if passages else math.nan,
        }
        if yaw_error is not None:
            out[kind]["yaw"] = heading_inside(mine, t, yaw_error)
    return out


def heading_inside(windows: list[win.Window], t: np.ndarray, yaw_error: np.ndarray) -> dict:
    """p95 and max of the heading error (deg) over the scans at times `t` inside any of `windows` (NaN: none inside)."""
    inside = np.zeros(len(t), dtype=bool)
    for w in windows:
        inside |= w.scans(t)
    heading = yaw_error[inside]
    heading = heading[np.isfinite(heading)]
    if not len(heading):
        return {"p95": math.nan, "max": math.nan}
    return {"p95": float(np.percentile(heading, 95)), "max": float(heading.max())}


def _nanmax(values: list[float]) -> float:
    v = np.asarray(values, dtype=float)
    return float(np.nanmax(v)) if np.isfinite(v).any() else math.nan


def monitor_metrics(fixes: FixTable, eid: str) -> dict:
    """Precision, recall and false-alarm rate of the estimator's verdicts on measured fixes, for both
    fault definitions, and the best recall at <= 5% false alarms from the ROC of its statistic."""
    measured = fixes.measured
    flagged = ~fixes.trusted[eid][measured]
    statistic = fixes.statistic[eid][measured]
    out = {}
    for name, faulty in (("error_5m", fixes.horizontal_error[measured] > FAULT_M), ("added_5m", fixes.added_error[measured] > FAULT_M)):
        tp = int((flagged & faulty).sum())
        out[name] = {
            "faulty": int(faulty.sum()),
            "precision": tp / int(flagged.sum()) if flagged.any() else math.nan,
            "recall": tp / int(faulty.sum()) if faulty.any() else math.nan,
            "false_alarm_rate": float((flagged & ~faulty).sum() / (~faulty).sum()) if (~faulty).any() else math.nan,
            "recall_at_5pct_fa": recall_at(statistic, faulty, FALSE_ALARM_BUDGET),
        }
    return out


def roc(statistic: np.ndarray, faulty: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """False-alarm rate, recall and threshold for every distinct threshold (flag when >=; NaN never flagged)."""
    s = np.where(np.isnan(statistic), -np.inf, statistic)
    order = np.argsort(-s, kind="stable")
    s_sorted, f_sorted = s[order], faulty[order]
    last = np.r_[np.nonzero(s_sorted[1:] != s_sorted[:-1])[0], len(s) - 1] if len(s) else np.zeros(0, dtype=int)
    tp, fp = np.cumsum(f_sorted)[last], np.cumsum(~f_sorted)[last]
    n_pos, n_neg = max(int(faulty.sum()), 1), max(int((~faulty).sum()), 1)
    keep = np.isfinite(s_sorted[last])
    return np.r_[0.0, fp[keep] / n_neg], np.r_[0.0, tp[keep] / n_pos], np.r_[np.inf, s_sorted[last][keep]]


def recall_at(statistic: np.ndarray, faulty: np.ndarray, max_fa: float) -> float:
    """Best recall with a false-alarm rate <= max_fa on the statistic's ROC (NaN without faulty fixes)."""
    if not faulty.any():
        return math.nan
    fa, rec, _ = roc(statistic, faulty)
    return float(rec[fa <= max_fa + 1e-12].max())


def matcher_metrics(rec: RunRecord, mid: str) -> dict:
    """success: share of scans after the first whose match is usable (gated scans count as not);
    gated: share of all scans the point-count gate dropped; degenerate: share of usable matches
    with an unobserved direction; hz and ms from the wall time per registered scan (not gated, not the first)."""
    m = rec.matches[mid]
    attempts = np.arange(len(m.ok)) > 0  # the first scan has nothing to match against
    registered = attempts & ~m.gated  # a gated scan is dropped before registration: it costs nothing
    seconds = m.seconds[registered]
    out = {
        "success": float(m.ok[attempts].mean()) if attempts.any() else math.nan,
        "gated": float(m.gated.mean()) if len(m.gated) else math.nan,
        "degenerate": float(m.degenerate[m.ok].mean()) if m.ok.any() else math.nan,
        "hz": float(1.0 / np.median(seconds)) if len(seconds) and np.median(seconds) > 0 else math.nan,
        "ms": {
            "median": float(1e3 * np.median(seconds)) if len(seconds) else math.nan,
            "p95": float(1e3 * np.percentile(seconds, 95)) if len(seconds) else math.nan,
        },
        "points": {
            "median": float(np.median(m.points)) if len(m.points) else math.nan,
            "p10": float(np.percentile(m.points, 10)) if len(m.points) else math.nan,
            "p90": float(np.percentile(m.points, 90)) if len(m.points) else math.nan,
        },
        **odometry_metrics(m.pose, rec.truth),
    }
    failed = [f for f in rec.failures if f["component"] == "matcher" and f["id"] == mid]
    out["failed"] = bool(failed)
    if failed:
        out["failed_at"] = failed[0]["stamp"]
    return out


def odometry_metrics(pose: np.ndarray, truth: np.ndarray) -> dict:
    """What odometry laid onto the world (N, 4, 4) at the scan times is scored by against the truth there: ape, ape_aligned
    (after the best-fit rigid planar motion, align_se2), rpe per distance and yaw (what every matcher gets, built in or
    scored in afterwards by scenarios.pipeline.rescore)."""
    return {
        "ape": stats(horizontal_error(pose, truth)),
        "ape_aligned": stats(horizontal_error(align_se2(pose, truth), truth)),
        **{f"rpe_{d:g}m": rpe(pose, truth, d) for d in RPE_DISTANCES_M},
        "yaw": stats(yaw_error_deg(pose, truth)),
    }


def gps_metrics(fixes: FixTable) -> dict:
    measured = fixes.measured
    n = len(fixes.t)
    error = fixes.horizontal_error[measured]
    return {
        "fixes": n,
        "availability": float(measured.mean()) if n else math.nan,
        "valid": float((fixes.quality != 0).mean()) if n else math.nan,
        "blackout": float((~measured).mean()) if n else math.nan,
        "nlos_share": float(fixes.nlos_used[measured].mean()) if measured.any() else math.nan,
        "error": stats(error),
        "open_sky_error": stats(np.hypot(*fixes.open_sky_error[measured, :2].T)),
        "added_error": stats(fixes.added_error[measured]),
        "hdop_median": float(np.nanmedian(fixes.hdop[measured])) if measured.any() else math.nan,
        "faulty_5m": float((error > FAULT_M).mean()) if measured.any() else math.nan,
    }


def compute(rec: RunRecord, windows: list[win.Window], run_info: dict, vessel: dict, alert_limit_m: float = ALERT_LIMIT_M) -> dict:
    """The metrics tree (NaN where nothing could be measured; written as null in JSON); `vessel` from scenarios.score.vessel_log.metrics.
    A run with a magnetic compass also has `compass` (its own heading error) and `estimators.<id>.compass` for those fed it."""
    tree = {
        "run": run_info,
        "gps": gps_metrics(rec.fixes),
        "vessel": vessel,
        "estimators": {eid: estimator_metrics(rec, eid, windows, alert_limit_m) for eid in rec.estimates},
        "matchers": {mid: matcher_metrics(rec, mid) for mid in rec.matches},
    }
    if rec.headings is not None:
        tree["compass"] = compass_metrics(rec.headings)
        for eid, used in rec.headings.used.items():
            tree["estimators"][eid]["compass"] = compass_use_metrics(rec.headings, used)
    return tree


COMPASS_DISTURBED_DEG = 3.0
"""A compass heading off the truth by more than this is disturbed (steel nearby): a filter should not use it."""


def compass_metrics(headings: HeadingTable) -> dict:
    """The compass's own heading error, deg (abs: rmse, mean, median, p95, max), and its disturbed share and seconds."""
    err = np.degrees(np.abs(headings.error))
    period = float(np.median(np.diff(headings.t))) if len(headings.t) > 1 else math.nan
    disturbed = err > COMPASS_DISTURBED_DEG
    return {"yaw": stats(err), "disturbed": float(disturbed.mean()) if len(err) else math.nan, "disturbed_s": float(disturbed.sum() * period)}


def compass_use_metrics(headings: HeadingTable, used: np.ndarray) -> dict:
    """How an estimator used the compass: share of headings used, and the share of disturbed headings it used (the gate's misses)."""
    disturbed = np.degrees(np.abs(headings.error)) > COMPASS_DISTURBED_DEG
    return {
        "used": float(used.mean()) if len(used) else math.nan,
        "disturbed_used": float(used[disturbed].mean()) if disturbed.any() else math.nan,
    }


def json_safe(tree):
    """NaN and infinities as None (JSON has neither), numpy scalars as Python numbers."""
    if isinstance(tree, dict):
        return {k: json_safe(v) for k, v in tree.items()}
    if isinstance(tree, (list, tuple)):
        return [json_safe(v) for v in tree]
    if isinstance(tree, (np.floating, float)):
        return float(tree) if math.isfinite(tree) else None
    if isinstance(tree, np.integer):
        return int(tree)
    if isinstance(tree, np.bool_):
        return bool(tree)
    return tree
