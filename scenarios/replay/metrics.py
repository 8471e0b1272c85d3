"""What a replay can measure without truth, nested as its metrics.json.

- `gps`: fixes, shares measured (GGA quality 1, 2, 4 or 5), valid (not 0) and dead reckoning (6), median HDOP.
- `matchers.<id>`: success, gated, degenerate, hz, ms, points, failed (as scenarios.score.metrics counts them).
- `estimators.<id>`: available (share of scans with a pose), failed, and `against_gps`: the
  horizontal distance from the estimate's antenna (base_link pose times the scenario's antenna
  offset, interpolated between the scans around each fix) to every measured fix its own monitor
  trusted: `trusted` (share of measured fixes), `fixes` (compared) and its rmse, mean, median,
  p95, max. The GPS track is a reference only where the monitor trusts it, and it has its own
  error: these are distances to GPS, not errors against truth.
"""

from __future__ import annotations

import math

import numpy as np

from fusion.observation import DEAD_RECKONING, POSITION_QUALITIES
from scenarios.score import metrics
from scenarios.score.record import FixTable, RunRecord

MATCHER_KEYS = ("success", "gated", "degenerate", "hz", "ms", "points", "failed", "failed_at")
"""The matcher metrics that need no truth."""


def compute(rec: RunRecord, run_info: dict, antenna: np.ndarray, startups: dict[str, dict] | None = None) -> dict:
    """The metrics tree (NaN where nothing could be measured; null in JSON); `startups`: each estimator's startup() (none
    given: empty)."""
    startups = startups or {}
    return {
        "run": run_info,
        "gps": gps_metrics(rec.fixes),
        "estimators": {eid: {**estimator_metrics(rec, eid, antenna), "startup": startups.get(eid, {})} for eid in rec.estimates},
        "matchers": {mid: {k: v for k, v in metrics.matcher_metrics(rec, mid).items() if k in MATCHER_KEYS} for mid in rec.matches},
    }


def measured(fixes: FixTable) -> np.ndarray:
    """Fixes with a measured position (not the receiver's dead reckoning, not invalid)."""
    return np.isin(fixes.quality, sorted(POSITION_QUALITIES))


def startup(estimator: object, t_start: float) -> dict:
    """How an estimator started: when it had a position and a heading (s after the recording's start, NaN: never) and what
    gave the heading (fusion.bootstrap.HEADING_*: motion, a compass, the course over ground, or none yet: it started at
    rest); empty for an estimator that does not say (a plugin)."""
    heading_from = getattr(estimator, "heading_from", None)
    if not isinstance(heading_from, str):
        return {}
    position_at, heading_at = (float(getattr(estimator, name, math.nan)) for name in ("position_at", "heading_at"))
    return {"position_s": position_at - t_start, "heading_s": heading_at - t_start, "heading_from": heading_from or "never started"}


def gps_metrics(fixes: FixTable) -> dict:
    """Shares of the receiver's fix qualities and its median HDOP."""
    n = len(fixes.t)
    share = lambda mask: float(mask.mean()) if n else math.nan
    good = measured(fixes)
    hdop = fixes.hdop[good]
    return {
        "fixes": n,
        "measured": share(good),
        "valid": share(fixes.quality != 0),
        "dead_reckoning": share(fixes.quality == DEAD_RECKONING),
        "hdop_median": float(np.nanmedian(hdop)) if np.isfinite(hdop).any() else math.nan,
    }


def estimator_metrics(rec: RunRecord, eid: str, antenna: np.ndarray) -> dict:
    """Availability, failure and the distance to the fixes the estimator's monitor trusted."""
    est = rec.estimates[eid]
    has = np.isfinite(est).all(axis=(1, 2))
    good = measured(rec.fixes)
    trusted = good & rec.fixes.trusted[eid]
    distance = np.full(int(trusted.sum()), math.nan)
    if has.sum() >= 1 and trusted.any():
        position = est[has, :3, :3] @ antenna + est[has, :3, 3]
        at = rec.fixes.t[trusted]
        xy = np.stack([np.interp(at, rec.scan_t[has], position[:, k], left=math.nan, right=math.nan) for k in (0, 1)], axis=1)
        distance = np.hypot(*(xy - rec.fixes.enu[trusted, :2]).T)
    out = {
        "available": float(has.mean()) if len(has) else math.nan,
        "against_gps": {
            "trusted": float(trusted.sum() / good.sum()) if good.any() else math.nan,
            "fixes": int(np.isfinite(distance).sum()),
            **metrics.stats(distance),
        },
    }
    failed = [f for f in rec.failures if f["component"] == "estimator" and f["id"] == eid]
    out["failed"] = bool(failed)
    if failed:
        out["failed_at"] = failed[0]["stamp"]
    return out
