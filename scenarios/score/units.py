"""The unit and the printed precision of every number of metrics.json, by dotted-path pattern (first match wins).

metrics.json carries each number rounded to the precision it supports and a top-level `units` block
(pattern -> unit) that says what it is measured in. The quanta lie far below every metric family's
regression tolerance (scenarios.score.metrics.FAMILIES: position 0.05 m, heading 0.1 deg, shares
0.005-0.03, recovery 0.5 s, drift 0.05 %), so a baseline recorded unrounded judges a rounded run as
unchanged (tests/test_run_metrics.py checks quantum <= tolerance / 100 for every family with a direction).

- metres: 1e-4 (0.1 mm; the TUM files print 1 um, GNSS errors are metres)
- degrees: 1e-3; percent of the distance travelled: 1e-3
- durations, s: 1e-3 (a scan lasts 0.1 s); stamps on the scenario clock (t_start, failed_at, ...): 1e-6 s,
  as they name a scan whose stamp the TUM files carry to the nanosecond
- shares (0-1): 1e-4 (one scan in 10,000); DOP: 1e-3; points per scan: 0.1
- wall clock: ms 1e-3, Hz 1e-3, real-time factor 1e-3, MB 0.1
- counts, seeds and 0/1 flags are integers and stay as they are
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fnmatch import fnmatchcase


@dataclass(frozen=True)
class Quantity:
    """What a group of metrics measures: its unit, the decimals it is rounded to (None: an integer, left as is), its paths."""

    unit: str
    decimals: int | None
    patterns: tuple[str, ...]


QUANTITIES: tuple[Quantity, ...] = (
    Quantity("s (scenario time)", 6, ("run.t_start", "run.t_end", "*.failed_at", "vessel.collision_t", "vessel.min_clearance_t")),
    Quantity(
        "s",
        3,
        (
            "run.sim_s",
            "run.wall_s",
            "run.duration_s",
            "estimators.*.windows.*.seconds",
            "estimators.*.windows.*.recover_s",
            "estimators.*.windows.*.settle_s",
            "vessel.time_below_threshold_s",
            "compass.disturbed_s",
            "*.external.wall_s",
            "*.external.cpu_s",
            "*.external.recording_s",
        ),
    ),
    Quantity("ms per registered scan", 3, ("matchers.*.ms.*",)),
    Quantity("Hz", 3, ("matchers.*.hz",)),
    Quantity("x real time", 3, ("run.realtime_factor",)),
    Quantity("MB", 1, ("run.peak_rss_mb", "*.external.peak_rss_mb")),
    Quantity("0/1", None, ("*.failed", "vessel.completed", "vessel.collisions")),
    Quantity(
        "count",
        None,
        (
            "run.seed",
            "run.scans",
            "run.fixes",
            "run.workers",
            "gps.fixes",
            "*.rpe_*m.pairs",
            "estimators.*.windows.*.count",
            "estimators.*.monitor.*.faulty",
            "estimators.*.against_gps.fixes",
            "estimators.*.integrity.misleading_epochs",
            "estimators.*.integrity.hazardous_epochs",
            "*.source.poses",
            "*.external.poses",
            "*.external.exit_code",
        ),
    ),
    Quantity("deg", 3, ("*.yaw.*",)),
    Quantity("% of the distance", 3, ("*.rpe_*m.percent",)),
    Quantity("points per scan", 1, ("matchers.*.points.*", "run.mover_points.median", "run.mover_points.p90", "run.mover_points.max")),
    Quantity("DOP (dimensionless)", 3, ("gps.hdop_median",)),
    Quantity(
        "share (0-1)",
        4,
        (
            "*.available",
            "*.coverage",
            "gps.availability",
            "gps.valid",
            "gps.blackout",
            "gps.nlos_share",
            "gps.faulty_5m",
            "gps.measured",
            "gps.dead_reckoning",
            "estimators.*.windows.*.recovered",
            "estimators.*.windows.*.settled",
            "estimators.*.integrity.misleading",
            "estimators.*.monitor.*.*",
            "estimators.*.against_gps.trusted",
            "matchers.*.success",
            "matchers.*.gated",
            "matchers.*.degenerate",
            "run.mover_points.scans_with",
            "compass.disturbed",
            "estimators.*.compass.used",
            "estimators.*.compass.disturbed_used",
        ),
    ),
    Quantity(
        "m",
        4,
        (
            "*.ape.*",
            "*.ape_aligned.*",
            "*.rpe_*m.*",
            "estimators.*.windows.*.*",
            "estimators.*.against_gps.*",
            "estimators.*.integrity.alert_limit_m",
            "estimators.*.integrity.hpl.*",
            "gps.error.*",
            "gps.open_sky_error.*",
            "gps.added_error.*",
            "vessel.min_clearance_m",
            "vessel.clearance_threshold_m",
            "vessel.distance_m",
            "vessel.cross_track.*",
        ),
    ),
)
"""Every number of metrics.json (a run's and a replay's), by the first quantity one of whose patterns its dotted path matches."""


def quantity_of(path: str) -> Quantity | None:
    """The quantity of a metric's dotted path (None when no pattern matches)."""
    return next((q for q in QUANTITIES if any(fnmatchcase(path, p) for p in q.patterns)), None)


def block() -> dict[str, str]:
    """metrics.json's `units` block: each pattern and its unit, in matching order (the first match wins)."""
    return {p: q.unit for q in QUANTITIES for p in q.patterns}


def rounded(tree: dict, path: str = "") -> dict:
    """The metrics tree (JSON-safe: no NaN) with each float rounded to its quantity's decimals; lists and text untouched."""
    out = {}
    for key, value in tree.items():
        here = f"{path}.{key}" if path else str(key)
        if isinstance(value, dict):
            out[key] = rounded(value, here)
        elif isinstance(value, float) and math.isfinite(value) and (q := quantity_of(here)) is not None and q.decimals is not None:
            out[key] = round(value, q.decimals) + 0.0  # + 0.0: no '-0.0'
        else:
            out[key] = value
    return out
