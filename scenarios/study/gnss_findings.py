"""Findings a-d measured on the receiver's fixes over the stretch: outages under each structure, the filter after an
outage, HDOP against the true error where reflected signals were used, and the error in open water.

Windows (blackout, nlos, reacquisition) are the run's own, scenarios.score.windows, from the same fixes and truth.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import spearmanr

from scenarios.score import metrics
from scenarios.score import windows as win
from scenarios.study.tasks import GnssSample

STRUCTURE_MARGIN_S = 20.0
"""A window within this of the vessel's passage under a structure's deck is that structure's (the receiver coasts up to
10 s, sim.gnss coast_limit_s, before it reports quality 0)."""
DEAD_RECKONING = 6
"""GGA quality of the receiver's coasting (NMEA 0183: 6 = estimated, dead reckoning)."""
MIN_LOS = 4
"""Fewer satellites than this in direct line of sight: no position from direct signals alone (the truth's outage)."""
OUTAGE_MIN_S = 1.0
"""Finding b looks after blackouts at least this long."""
OPEN_WATER_AWAY_M = 100.0
"""Open water: measured fixes at least this far along the route from every structure's deck ..."""
OPEN_WATER_AFTER_S = 10.0
"""... and this long after any blackout, NLOS or re-acquisition window, with no reflected signal used."""
ADDED_M = 0.5
"""d: a fix the environment (blockage, reflections) moved by more than this from the receiver's open-sky fix."""


def spans(t: np.ndarray, flag: np.ndarray, period_s: float) -> list[tuple[float, float]]:
    """[start, end) of each run of flagged epochs (end: the epoch after the run's last)."""
    out: list[tuple[float, float]] = []
    edges = np.diff(np.r_[0, flag.astype(int), 0])
    for a, b in zip(np.nonzero(edges == 1)[0], np.nonzero(edges == -1)[0]):
        out.append((float(t[a]), float(t[b]) if b < len(t) else float(t[b - 1] + period_s)))
    return out


def shadowed(structures: list[dict]) -> list[dict]:
    """The world's structures with a deck over the water (bridges, the lock's road), in route order."""
    return sorted((s for s in structures if "shadow_start_m" in s and "shadow_end_m" in s), key=lambda s: s["shadow_start_m"])


def open_water(g: GnssSample, windows: list[win.Window], structures: list[dict], reflections: bool = True) -> np.ndarray:
    """Mask of the open-water fixes (see OPEN_WATER_AWAY_M and OPEN_WATER_AFTER_S). With `reflections` False, also
    none within OPEN_WATER_AFTER_S after an epoch where a facade reflection reached a satellite used by its direct
    signal (code multipath, the truth's GnssSample.reflected): the study's open water as opposed to its finding c's
    'near walls', where multipath gives wrong fixes."""
    f = g.fixes
    keep = f.measured & ~f.nlos_used
    for s in structures:
        lo, hi = s.get("start_m", s["shadow_start_m"]), s.get("end_m", s["shadow_end_m"])
        keep &= (g.station < lo - OPEN_WATER_AWAY_M) | (g.station > hi + OPEN_WATER_AWAY_M)
    for w in windows:
        keep &= ~((f.t >= w.start) & (f.t < w.end + OPEN_WATER_AFTER_S))
    if not reflections and g.reflected is not None:
        for a, b in spans(f.t, g.reflected > 0, g.period_s):
            keep &= ~((f.t >= a) & (f.t < b + OPEN_WATER_AFTER_S))
    return keep


def outages(g: GnssSample, windows: list[win.Window], structures: list[dict]) -> dict:
    """Finding a: per structure passed, its passage (s under the deck) and the outages around it, in seconds, by source:
    quality 0 (the receiver reports nothing), no measured fix (quality != 1, the run's blackout windows) and fewer than
    MIN_LOS satellites in line of sight (the truth); beside them the share of the epochs under the deck without a
    measured fix and the fewest satellites in direct sight there (what holds a fix through the passage)."""
    f = g.fixes
    kinds = {
        "quality0_s": spans(f.t, f.quality == 0, g.period_s),
        "blackout_s": [(w.start, w.end) for w in windows if w.kind == "blackout"],
        "los_below_4_s": spans(f.t, g.los < MIN_LOS, g.period_s),
    }
    out = {}
    for s in shadowed(structures):
        under = (g.station >= s["shadow_start_m"]) & (g.station <= s["shadow_end_m"])
        if not under.any():
            continue
        t_in, t_out = float(f.t[under][0]), float(f.t[under][-1]) + g.period_s
        node = {
            "type": s.get("type", ""),
            "passage_start": t_in,
            "passage_s": t_out - t_in,
            "lost_share_under": float(np.mean(~f.measured[under])),
            "los_min_under": int(g.los[under].min()),
        }
        for key, found in kinds.items():
            near = [(a, b) for a, b in found if b > t_in - STRUCTURE_MARGIN_S and a < t_out + STRUCTURE_MARGIN_S]
            node[key] = float(sum(b - a for a, b in near))
        out[s["name"]] = node
    return {"structures": out, "margin_s": STRUCTURE_MARGIN_S}


def open_water_error(g: GnssSample, mask: np.ndarray) -> dict:
    """Finding d: horizontal error of the open-water fixes (m) and their HDOP; beside it the same receiver's error with
    nothing blocking or reflecting (the truth's open_sky_error) and what the environment added (its p95, the share of
    fixes it moved by more than ADDED_M and the route stations they lie between)."""
    f = g.fixes
    err = f.horizontal_error[mask]
    open_sky = np.hypot(f.open_sky_error[mask, 0], f.open_sky_error[mask, 1])
    added = f.added_error[mask]
    worst = added > ADDED_M
    return {
        "fixes": int(mask.sum()),
        "share_of_fixes": float(mask.mean()) if len(mask) else math.nan,
        "error": metrics.stats(err),
        "hdop_p95": float(np.percentile(f.hdop[mask], 95)) if mask.any() else math.nan,
        "open_sky_error": metrics.stats(open_sky),
        "added_p95_m": float(np.percentile(added, 95)) if mask.any() else math.nan,
        "added_share": float(worst.mean()) if mask.any() else math.nan,
        "added_stations_m": [float(np.min(g.station[mask][worst])), float(np.max(g.station[mask][worst]))] if worst.any() else None,
    }


def after_outages(g: GnssSample, windows: list[win.Window], open_p95: float, n_fixes: int) -> dict:
    """Finding b: for each blackout of at least OUTAGE_MIN_S, the mean and max error of the first `n_fixes` measured
    fixes after it, and how long after it the error first came back within open water's p95 (`settle_s`, NaN: not
    before the next outage or the stretch's end), the satellites the first fix used, how many of those fixes used a
    satellite received only by its reflection (the truth's NLOS flag: what a wrong fix at a deck's edge is made of), how
    long the receiver dead-reckoned in the outage and the error it had reached when it stopped; the run's
    re-acquisition windows beside."""
    f = g.fixes
    err = f.horizontal_error
    blackouts = [w for w in windows if w.kind == "blackout"]
    rows = []
    for i, w in enumerate(blackouts):
        if w.duration < OUTAGE_MIN_S:
            continue
        until = blackouts[i + 1].start if i + 1 < len(blackouts) else math.inf
        after = np.nonzero((f.t >= w.end) & (f.t < until) & f.measured)[0]
        if not len(after):
            continue
        first = err[after[:n_fixes]]
        coasted = np.nonzero((f.t >= w.start) & (f.t < w.end) & (f.quality == DEAD_RECKONING))[0]
        back = after[err[after] <= open_p95] if math.isfinite(open_p95) else after[:0]
        rows.append(
            {
                "end": w.end,
                "outage_s": w.duration,
                "first_mean_m": float(first.mean()),
                "first_max_m": float(first.max()),
                "settle_s": float(f.t[back[0]] - w.end) if len(back) else math.nan,
                "first_sats": int(f.num_sats[after[0]]),
                "first_reflected": int(f.nlos_used[after[:n_fixes]].sum()),
                "coasted_s": float(len(coasted) * g.period_s),
                "coast_end_error_m": float(err[coasted[-1]]) if len(coasted) else math.nan,
            }
        )
    reacq = [w for w in windows if w.kind == "reacquisition"]
    settle = np.array([r["settle_s"] for r in rows])
    return {
        "outages": rows,
        "first_fixes": n_fixes,
        "open_water_p95_m": open_p95,
        "wrong_share": float(np.mean([r["first_mean_m"] > open_p95 for r in rows])) if rows and math.isfinite(open_p95) else math.nan,
        "first_mean_m_median": float(np.median([r["first_mean_m"] for r in rows])) if rows else math.nan,
        "settle_s_median": float(np.nanmedian(settle)) if np.isfinite(settle).any() else math.nan,
        "reacquisition_windows": len(reacq),
        "reacquisition_s_median": float(np.median([w.duration for w in reacq])) if reacq else math.nan,
    }


def between(stations_m: list[float] | None, decks: list[dict]) -> list[str]:
    """The structures on either side of the route stations [lo, hi] (the last deck before lo, the first after hi)."""
    if not stations_m:
        return []
    before = [s["name"] for s in decks if s["shadow_end_m"] <= stations_m[0]]
    after = [s["name"] for s in decks if s["shadow_start_m"] >= stations_m[1]]
    return [before[-1] if before else "the route's start", after[0] if after else "the route's end"]


def roc_auc(statistic: np.ndarray, faulty: np.ndarray) -> float:
    """Area under the ROC of `statistic` as a detector of `faulty` (0.5: chance; NaN without both classes)."""
    if not (faulty.any() and (~faulty).any()):
        return math.nan
    fa, rec, _ = metrics.roc(statistic, faulty)
    fa, rec = np.r_[fa, 1.0], np.r_[rec, 1.0]
    return float(np.sum(np.diff(fa) * (rec[1:] + rec[:-1]) / 2.0))


def hdop_vs_error(g: GnssSample, windows: list[win.Window], open_hdop_p95: float) -> dict:
    """Finding c, on the measured fixes in the NLOS windows (where reflections reach the receiver): Spearman correlation
    of HDOP with the true horizontal error, the area under the ROC of HDOP as a detector of faulty fixes (error >
    metrics.FAULT_M) and the faulty fixes' median HDOP (against open water's p95); the AUC over every measured fix beside."""
    f = g.fixes
    measured = f.measured
    err, hdop = f.horizontal_error, f.hdop
    in_nlos = np.zeros(len(f.t), dtype=bool)
    for w in windows:
        if w.kind == "nlos":
            in_nlos |= (f.t >= w.start) & (f.t < w.end)
    sel = measured & in_nlos
    rho = float(spearmanr(hdop[sel], err[sel]).statistic) if sel.sum() >= 3 and np.ptp(hdop[sel]) > 0 and np.ptp(err[sel]) > 0 else math.nan
    faulty = err[sel] > metrics.FAULT_M
    return {
        "nlos_fixes": int(sel.sum()),
        "spearman_nlos": rho,
        "faulty_fixes": int(faulty.sum()),
        "fault_m": metrics.FAULT_M,
        "roc_auc": roc_auc(hdop[sel], faulty),
        "roc_auc_all_fixes": roc_auc(hdop[measured], err[measured] > metrics.FAULT_M),
        "faulty_hdop_median": float(np.median(hdop[sel][faulty])) if faulty.any() else math.nan,
        "open_water_hdop_p95": open_hdop_p95,
    }


def measure(g: GnssSample, structures: list[dict], n_fixes: int) -> dict:
    """Findings a-d from one receiver's fixes over the stretch. Finding d is judged on the open water no facade
    reflection reaches (open_water with reflections=False), and b's 'wrong' is beyond that open water's p95; the
    figures with those fixes kept are beside it (`with_reflections`), with where the reflections moved the fixes. c's
    HDOP reference is the route's open water with them kept: a reflection on a direct signal changes the range, not
    the geometry HDOP is computed from, so leaving those epochs out would only sample the geometry elsewhere."""
    windows = win.find(g.fixes, [], g.period_s)
    decks = shadowed(structures)
    d = open_water_error(g, open_water(g, windows, decks, reflections=False))
    d["with_reflections"] = open_water_error(g, open_water(g, windows, decks))
    d["with_reflections"]["between"] = between(d["with_reflections"]["added_stations_m"], decks)
    return {
        "a": outages(g, windows, structures),
        "b": after_outages(g, windows, d["error"]["p95"], n_fixes),
        "c": hdop_vs_error(g, windows, d["with_reflections"]["hdop_p95"]),
        "d": d,
    }
