"""Screen a receiver fix into what the filters use: antenna position and its covariance from HDOP."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from sim.gnss_fix import GnssFix, SatelliteReport

POSITION_QUALITIES = frozenset({1, 2, 4, 5})
"""GGA qualities that are a measured position: GPS, DGPS, RTK fixed, RTK float."""
DEAD_RECKONING = 6


@dataclass(frozen=True)
class FixObservation:
    """A usable fix: antenna (x, y) in world ENU, its 2x2 covariance, height and its variance, the receiver's
    per-satellite reports (GSV/GSA: prn, az, el, C/N0, used) for monitors that read them, and its speed over ground
    (m/s) and course (deg clockwise from north; RMC/VTG), NaN when it gives none."""

    stamp: float
    xy: np.ndarray
    cov: np.ndarray
    z: float
    z_var: float
    quality: int
    hdop: float
    sats: tuple[SatelliteReport, ...] = ()
    speed_mps: float = math.nan
    course_deg: float = math.nan
    allowance_m: float = 0.0
    """Error a monitor could not rule out in this trusted fix (fusion.Verdict.allowance_m), m, 1 sigma per horizontal axis:
    the filters add its square to the fix's measurement noise (0: none)."""

    @property
    def ground_velocity(self) -> np.ndarray | None:
        """The receiver's velocity over ground in world ENU (east, north), m/s, from its speed and course; None without them."""
        if not (math.isfinite(self.speed_mps) and math.isfinite(self.course_deg)):
            return None
        course = math.radians(self.course_deg)  # clockwise from north
        return self.speed_mps * np.array([math.sin(course), math.cos(course)])


def screen(fix: GnssFix, uere_m: float, accept_dead_reckoning: bool) -> tuple[FixObservation | None, str]:
    """The fix as an observation, or None with the reason it cannot be used as a position."""
    try:
        quality = int(fix.quality)
    except (TypeError, ValueError):
        return None, f"bad field 'quality'={fix.quality!r}"
    if quality == 0:
        return None, "no fix (GGA quality 0)"
    if quality == DEAD_RECKONING and not accept_dead_reckoning:
        return None, "receiver dead reckoning (GGA quality 6)"
    if quality not in POSITION_QUALITIES and quality != DEAD_RECKONING:
        return None, f"unsupported GGA quality {quality}"
    enu = np.asarray(fix.enu, dtype=float).reshape(-1)
    if enu.size != 3 or not np.all(np.isfinite(enu)):
        return None, f"bad field 'enu'={fix.enu!r}"
    hdop = float(fix.hdop)
    if not math.isfinite(hdop) or hdop <= 0:
        return None, f"bad field 'hdop'={fix.hdop!r}"
    vdop = float(fix.vdop) if math.isfinite(float(fix.vdop)) and fix.vdop > 0 else 2.0 * hdop
    sigma_axis = uere_m * hdop / math.sqrt(2.0)
    return (
        FixObservation(
            stamp=float(fix.stamp),
            xy=enu[:2].copy(),
            cov=np.eye(2) * sigma_axis**2,
            z=float(enu[2]),
            z_var=(uere_m * vdop) ** 2,
            quality=quality,
            hdop=hdop,
            sats=tuple(getattr(fix, "sats", ()) or ()),
            speed_mps=_finite(getattr(fix, "speed_mps", math.nan)),
            course_deg=_finite(getattr(fix, "course_deg", math.nan)),
        ),
        "",
    )


def allowing(obs: FixObservation, allowance_m: float) -> FixObservation:
    """The fix carrying a monitor's allowance (Verdict.allowance_m, 1 sigma per horizontal axis) for the filters' update."""
    if not allowance_m > 0:
        return obs
    return replace(obs, allowance_m=float(allowance_m))


SCREEN_RULES = (
    ("bad field", "input.bad_field"),
    ("no fix", "input.no_fix"),
    ("receiver dead reckoning", "input.dead_reckoning"),
    ("unsupported", "input.unsupported"),
)
"""The Verdict.rule of each reason `screen` gives (by its opening words)."""


def screen_rule(why: str) -> str:
    """The Verdict.rule of a reason `screen` gave for not using a fix."""
    return next((rule for opening, rule in SCREEN_RULES if why.startswith(opening)), "input.other")


def _finite(value: object) -> float:
    """A finite float, else NaN (a plugin's fix may carry anything in an optional field)."""
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return math.nan
    return number if math.isfinite(number) else math.nan
