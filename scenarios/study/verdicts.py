"""The verdict rules: each finding becomes checks (a claim of the study, the study's figure, the bench's measured value,
whether it holds) and its verdict follows from them: `agrees` when every measured check holds, `disagrees` when none
does, `partly` otherwise, `unmeasured` when the stretch gave no data for any. Every threshold is named here."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from scenarios.study.findings import Finding

VERDICTS = ("agrees", "partly", "disagrees", "unmeasured")
WRONG_SHARE = 0.5
"""b: the filter 'smooths a wrong fix' when at least this share of outages is followed by fixes off by more than open water's p95."""
SMOOTHING_MIN_S = 1.0
"""b: 'for a while': the error takes at least this long (median over outages) to come back within open water's p95."""
WEAK_RHO = 0.3
"""c: HDOP does not track the error when their Spearman correlation is below this; e: Method 1's time depends on the
points per scan when theirs is above it (its CPU time: the process's own work, where the wall time on a shared machine
also carries the other processes' load; the wall time's correlation is reported beside)."""
POOR_AUC = 0.7
"""c: HDOP is a poor fault detector when the area under its ROC is below this (0.5: chance, 1: perfect)."""
SUCCEEDS = 0.8
"""f: matching 'succeeds' in a points band when at least this share of its registrations is ok ..."""
FAILS = 0.5
"""... and 'fails mostly' when under this share is."""
MIN_COUNT = 10
"""f: a band with fewer registrations than this is not judged."""
POINT_SHARES = ("outlier_share", "rejected_share", "plane_outlier_share")
"""g: the diagnostics that are shares of points (the study's 'of the points'): pcl6d's ICP outlier share, gicp's
rejected and plane-outlier shares. pcl6d's prealign_rejected_share counts FPFH feature correspondences, not points
(63% of a sparse scan's mutual feature matches are rejected while 95% of its points find a partner): reported, not judged."""
DRIFT_FACTOR = 2.0
"""h: the drift agrees when within this factor of the study's figure, either way."""


@dataclass(frozen=True)
class Check:
    """One claim checked: the study's figure and the bench's value as text, and whether the claim holds (None: no data)."""

    claim: str
    study: str
    measured: str
    holds: bool | None

    def as_dict(self) -> dict:
        return asdict(self)


def verdict(checks: list[Check]) -> str:
    """agrees / partly / disagrees from the measured checks; unmeasured when none was measured."""
    judged = [c.holds for c in checks if c.holds is not None]
    if not judged:
        return "unmeasured"
    return "agrees" if all(judged) else "disagrees" if not any(judged) else "partly"


def _f(value, fmt: str = ".2f", unit: str = "") -> str:
    return "n/a" if value is None or not math.isfinite(value) else format(value, fmt) + unit


def _holds(value, test) -> bool | None:
    return None if value is None or not math.isfinite(value) else bool(test(value))


def checks_a(m: dict, finding: Finding) -> list[Check]:
    out = []
    for name, s in m["structures"].items():
        measured = (
            f"{_f(s['blackout_s'], '.1f', ' s')} without a measured fix ({_f(s['quality0_s'], '.1f', ' s')} quality 0, "
            f"truth: {_f(s['los_below_4_s'], '.1f', ' s')} with < 4 satellites in sight)"
        )
        out.append(Check(f"GPS drops out under {name}", "drops out", measured, s["blackout_s"] > 0.0))
    return out


def checks_b(m: dict, finding: Finding) -> list[Check]:
    n = len(m["outages"])
    p95 = m["open_water_p95_m"]
    return [
        Check(
            f"the first {m['first_fixes']} fixes after an outage are off by more than open water's p95 (in >= {WRONG_SHARE:.0%} of outages)",
            "a wrong estimate",
            f"{_f(m['wrong_share'] * 100 if n else math.nan, '.0f', ' %')} of {n} outages; "
            f"median {_f(m['first_mean_m_median'], '.2f', ' m')} vs p95 {_f(p95, '.2f', ' m')}",
            _holds(m["wrong_share"], lambda v: v >= WRONG_SHARE),
        ),
        Check(
            f"for a while: the error is back within open water's p95 only after >= {SMOOTHING_MIN_S:g} s (median)",
            "for a while",
            _f(m["settle_s_median"], ".1f", " s"),
            _holds(m["settle_s_median"], lambda v: v >= SMOOTHING_MIN_S),
        ),
    ]


def checks_c(m: dict, finding: Finding) -> list[Check]:
    return [
        Check(
            f"HDOP does not track the error where reflected signals were used (Spearman < {WEAK_RHO})",
            "HDOP stays low",
            f"rho {_f(m['spearman_nlos'])} over {m['nlos_fixes']} fixes",
            _holds(m["spearman_nlos"], lambda v: v < WEAK_RHO),
        ),
        Check(
            f"HDOP is a poor detector of the fixes off by > {m['fault_m']:g} m there (ROC AUC < {POOR_AUC})",
            "not a reliable indicator",
            f"AUC {_f(m['roc_auc'])} ({m['faulty_fixes']} faulty fixes in NLOS windows)",
            _holds(m["roc_auc"], lambda v: v < POOR_AUC),
        ),
        Check(
            "those faulty fixes' HDOP stays low (median within open water's p95)",
            "HDOP stays low",
            f"{_f(m['faulty_hdop_median'])} vs {_f(m['open_water_hdop_p95'])}",
            _holds(m["faulty_hdop_median"] - m["open_water_hdop_p95"], lambda v: v <= 0.0),
        ),
    ]


def checks_d(m: dict, finding: Finding) -> list[Check]:
    limit = finding.figures["open_water_error_m"]
    e = m["error"]
    return [
        Check(
            f"open-water p95 horizontal error < {limit:g} m",
            f"< {limit:g} m",
            f"{_f(e['p95'], '.2f', ' m')} ({m['fixes']} fixes)",
            _holds(e["p95"], lambda v: v < limit),
        ),
        Check(
            f"open-water median horizontal error < {limit:g} m",
            f"< {limit:g} m",
            _f(e["median"], ".2f", " m"),
            _holds(e["median"], lambda v: v < limit),
        ),
    ]


def checks_e(m: dict, finding: Finding) -> list[Check]:
    lo, hi = finding.figures["method1_hz"]
    floor = finding.figures["method2_min_hz"]
    p, b = m.get("pcl6d", {}), m.get("bev3dof", {})
    nan = math.nan
    return [
        Check(
            f"Method 1 (pcl6d) runs at {lo:g}-{hi:g} Hz",
            f"{lo:g}-{hi:g} Hz",
            _f(p.get("hz", nan), ".1f", " Hz"),
            _holds(p.get("hz", nan), lambda v: lo <= v <= hi),
        ),
        Check(
            f"Method 1's work grows with the points per scan (Spearman of its CPU time > {WEAK_RHO})",
            "depends on points",
            f"rho {_f(p.get('spearman_cpu_seconds_points', nan))} (wall time: {_f(p.get('spearman_seconds_points', nan))})",
            _holds(p.get("spearman_cpu_seconds_points", nan), lambda v: v > WEAK_RHO),
        ),
        Check(
            f"Method 2 (bev3dof) runs at >= {floor:g} Hz",
            f">= {floor:g} Hz",
            _f(b.get("hz", nan), ".1f", " Hz"),
            _holds(b.get("hz", nan), lambda v: v >= floor),
        ),
        Check(
            "Method 2 is less precise (median translation error of its ok matches above Method 1's)",
            "lower precision",
            f"{_f(b.get('error_m_median', nan), '.3f', ' m')} vs {_f(p.get('error_m_median', nan), '.3f', ' m')}",
            _holds(b.get("error_m_median", nan) - p.get("error_m_median", nan), lambda v: v > 0.0),
        ),
        Check(
            "Method 2 leaves more matches unresolved",
            "more unresolved",
            f"{_f(100 * b.get('unresolved', nan), '.1f', ' %')} vs {_f(100 * p.get('unresolved', nan), '.1f', ' %')}",
            _holds(b.get("unresolved", nan) - p.get("unresolved", nan), lambda v: v > 0.0),
        ),
    ]


def checks_f(m: dict, finding: Finding, judged: tuple[str, ...] | None = None) -> list[Check]:
    lo, hi = finding.figures["points_band"]
    out = []
    for mid, s in m["matchers"].items():
        if judged is not None and mid not in judged:
            continue
        band = s["band_success"] if s["band_count"] >= MIN_COUNT else math.nan
        below = s["below_success"] if s["below_count"] >= MIN_COUNT else math.nan
        out.append(
            Check(
                f"{mid} succeeds for {lo:,}-{hi:,} points (>= {SUCCEEDS:.0%} ok)",
                "succeeds",
                f"{_f(100 * s['band_success'], '.0f', ' %')} of {s['band_count']}",
                _holds(band, lambda v: v >= SUCCEEDS),
            )
        )
        out.append(
            Check(
                f"{mid} fails mostly below {lo:,} points (< {FAILS:.0%} ok)",
                "fails mostly",
                f"{_f(100 * s['below_success'], '.0f', ' %')} of {s['below_count']}",
                _holds(below, lambda v: v < FAILS),
            )
        )
    return out


def checks_g(m: dict, finding: Finding, judged: tuple[str, ...] | None = None) -> list[Check]:
    limit = finding.figures["outlier_share"]
    out = []
    for mid, node in m.items():
        if judged is not None and mid not in judged:
            continue
        for key, s in node.items():
            if key not in POINT_SHARES:
                continue
            out.append(
                Check(
                    f"{mid} {key}: under {limit:.0%} rejected (median)",
                    f"< {limit:.0%}",
                    f"{_f(100 * s['median'], '.1f', ' %')} (p90 {_f(100 * s['p90'], '.1f', ' %')}, {s['n']})",
                    _holds(s["median"], lambda v: v < limit),
                )
            )
    return out


def checks_h(m: dict, finding: Finding) -> list[Check]:
    fig = finding.figures["yaw_drift_deg"]
    drift = abs(m["drift_end_deg"]) if math.isfinite(m["drift_end_deg"]) else math.nan
    return [
        Check(
            f"{m['matcher']} odometry's yaw drifts by the study's order at the end ({fig / DRIFT_FACTOR:g}-{fig * DRIFT_FACTOR:g} deg)",
            f"{fig:g} deg",
            f"{_f(m['drift_end_deg'], '.1f', ' deg')} after {_f(m['distance_m'], '.0f', ' m')}",
            _holds(drift, lambda v: fig / DRIFT_FACTOR <= v <= fig * DRIFT_FACTOR),
        ),
        Check(
            "the compass holds the heading better (drift at the end above the compass's p95 error)",
            "compass better",
            f"{_f(drift, '.1f', ' deg')} vs {_f(m['compass_p95_deg'], '.1f', ' deg')}",
            _holds(drift - m["compass_p95_deg"], lambda v: v > 0.0),
        ),
    ]


RULES = {"a": checks_a, "b": checks_b, "c": checks_c, "d": checks_d, "e": checks_e, "f": checks_f, "g": checks_g, "h": checks_h}
"""The checks of each finding, by key."""
BY_MATCHER = ("f", "g")
"""The findings whose checks take the matchers a setup judges (setups.Setup.judged_matchers)."""


def headline(key: str, m: dict) -> str:
    """The finding's key measured numbers in one line (the verdict table's bench column)."""
    nan = math.nan
    if key == "a":
        s = m["structures"]
        out = sum(v["blackout_s"] > 0 for v in s.values())
        lengths = ", ".join(f"{name} {_f(v['blackout_s'], '.0f')}" for name, v in s.items())
        return f"outage under {out} of {len(s)} structures; s without a measured fix: {lengths}"
    if key == "b":
        return (
            f"{len(m['outages'])} outages: first {m['first_fixes']} fixes' median error {_f(m['first_mean_m_median'], '.2f', ' m')} "
            f"(open water p95 {_f(m['open_water_p95_m'], '.2f', ' m')}), back within it after {_f(m['settle_s_median'], '.1f', ' s')} (median)"
        )
    if key == "c":
        return (
            f"in NLOS windows: Spearman(HDOP, error) {_f(m['spearman_nlos'])}, ROC AUC for > {m['fault_m']:g} m {_f(m['roc_auc'])} "
            f"({m['faulty_fixes']} of {m['nlos_fixes']} fixes); AUC over every fix {_f(m['roc_auc_all_fixes'])}"
        )
    if key == "d":
        return f"open-water error p95 {_f(m['error']['p95'], '.2f', ' m')}, median {_f(m['error']['median'], '.2f', ' m')} ({m['fixes']} fixes)"
    if key == "e":
        return "; ".join(
            f"{mid} {_f(v['hz'], '.0f', ' Hz')} (CPU time: {_f(v.get('cpu_hz', nan), '.0f', ' Hz')}), "
            f"{_f(100 * v['unresolved'], '.0f', ' %')} unresolved, {_f(v['error_m_median'], '.3f', ' m')}"
            for mid, v in m.items()
        )
    if key == "f":
        return "; ".join(
            f"{mid} {_f(100 * v['band_success'], '.0f', ' %')} ok in band ({v['band_count']}), "
            f"{_f(100 * v['below_success'], '.0f', ' %')} below ({v['below_count']})"
            for mid, v in m["matchers"].items()
        )
    if key == "g":
        parts = [f"{mid} {k} {_f(100 * s['median'], '.1f', ' %')}" for mid, node in m.items() for k, s in node.items()]
        return "; ".join(parts) or "no matcher reports outliers"
    if key == "h":
        return (
            f"{m['matcher']} over {_f(m.get('distance_m', nan), '.0f', ' m')}: yaw off by {_f(m['drift_end_deg'], '.1f', ' deg')} at the end "
            f"(max {_f(m['drift_max_deg'], '.1f', ' deg')}); its tilt off by {_f(m['tilt_end_deg'], '.1f', ' deg')} "
            f"(max {_f(m['tilt_max_deg'], '.1f', ' deg')}); compass p95 {_f(m['compass_p95_deg'], '.1f', ' deg')}"
        )
    raise KeyError(key)
