"""GPS constellation: a nominal almanac of 31 satellites on the 6-plane layout, ECEF positions at any UTC.

Orbits are circular (the GPS nominal design), inclined 55 deg, with the J2 regression of the
ascending node and a mean motion that repeats the ground track every sidereal day (two
revolutions, ~11 h 58 min each), which is how the operational constellation is kept.
The slot layout is the 27-slot reference constellation of the GPS SPS Performance Standard
(2008, Table A.2-2: 24 baseline slots plus the expanded B1, D2, F2 pairs), plus four spares in the
largest gaps of planes A, B, C and E, giving the ~31 satellites usually on orbit. The table's
angles are taken as this almanac's values at its time of applicability `ALMANAC_EPOCH`;
positions are refused more than `VALIDITY` away from it, as a receiver refuses a stale almanac.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np

MU_EARTH = 3.986005e14
"""WGS-84 gravitational parameter as used by GPS (IS-GPS-200), m^3/s^2."""
OMEGA_EARTH = 7.2921151467e-5
"""WGS-84 Earth rotation rate, rad/s."""
NODE_RATE = np.deg2rad(-4.4874e-7)
"""Nominal J2 regression of the ascending node for GPS orbits (SPS PS Table A.2-2), rad/s."""
INCLINATION = np.deg2rad(55.0)
MEAN_MOTION = 2.0 * (OMEGA_EARTH - NODE_RATE)
"""rad/s: two revolutions per revolution of the node in the Earth frame (repeating ground track)."""
RADIUS = (MU_EARTH / MEAN_MOTION**2) ** (1.0 / 3.0)
"""Orbit radius from Kepler's third law for MEAN_MOTION, ~26,561 km."""

ALMANAC_EPOCH = datetime(2024, 6, 1, tzinfo=UTC)
"""Time of applicability of the nominal almanac."""
VALIDITY = timedelta(days=180)
"""How far from ALMANAC_EPOCH positions are served; a real almanac is good for months."""

# Geographic longitude of the ascending node at the epoch (deg) per plane, as in the SPS PS table.
_PLANE_NODE_DEG = {"A": 357.734, "B": 57.734, "C": 117.734, "D": 177.734, "E": 237.734, "F": 297.734}
# (slot, plane, argument of latitude at the epoch in deg); PRNs are assigned in this order.
_SLOTS = (
    ("A1", "A", 268.126),
    ("A2", "A", 161.786),
    ("A3", "A", 11.676),
    ("A4", "A", 41.806),
    ("B1F", "B", 94.916),
    ("B1A", "B", 66.356),
    ("B2", "B", 173.336),
    ("B3", "B", 309.976),
    ("B4", "B", 204.376),
    ("C1", "C", 111.876),
    ("C2", "C", 11.796),
    ("C3", "C", 339.666),
    ("C4", "C", 241.556),
    ("D1", "D", 135.226),
    ("D2F", "D", 282.676),
    ("D2A", "D", 257.976),
    ("D3", "D", 35.156),
    ("D4", "D", 167.356),
    ("E1", "E", 197.046),
    ("E2", "E", 302.596),
    ("E3", "E", 66.066),
    ("E4", "E", 333.686),
    ("F1", "F", 238.886),
    ("F2F", "F", 0.456),
    ("F2A", "F", 334.016),
    ("F3", "F", 105.206),
    ("F4", "F", 135.346),
    # spares, mid-gap in the four planes with the largest gaps
    ("A5", "A", 101.796),
    ("B5", "B", 8.166),
    ("C5", "C", 176.716),
    ("E5", "E", 131.556),
)


@dataclass(frozen=True)
class Constellation:
    """Nominal GPS almanac: PRN numbers and orbital angles, vectorised over satellites."""

    prn: np.ndarray
    node0: np.ndarray
    arg_lat0: np.ndarray
    slot: tuple[str, ...]

    @classmethod
    def nominal(cls) -> Constellation:
        """The 31-satellite nominal almanac (PRN 1..31 in slot-table order)."""
        return cls(
            prn=np.arange(1, len(_SLOTS) + 1),
            node0=np.deg2rad([_PLANE_NODE_DEG[plane] for _, plane, _ in _SLOTS]),
            arg_lat0=np.deg2rad([u for _, _, u in _SLOTS]),
            slot=tuple(name for name, _, _ in _SLOTS),
        )

    def __len__(self) -> int:
        return len(self.prn)

    @staticmethod
    def seconds_since_epoch(utc: datetime) -> float:
        """Seconds from ALMANAC_EPOCH to `utc`; ValueError outside the almanac's validity."""
        if utc.tzinfo is None:
            raise ValueError(f"gnss: UTC time {utc.isoformat()} has no time zone (use UTC)")
        dt = utc - ALMANAC_EPOCH
        if abs(dt) > VALIDITY:
            raise ValueError(f"gnss: UTC time {utc.isoformat()} is outside the almanac's validity ({ALMANAC_EPOCH.date()} +/- {VALIDITY.days} days)")
        return dt.total_seconds()

    def ecef(self, seconds_since_epoch: float) -> np.ndarray:
        """(N, 3) ECEF positions in metres at `seconds_since_epoch` after ALMANAC_EPOCH."""
        dt = float(seconds_since_epoch)
        if not abs(dt) <= VALIDITY.total_seconds():
            raise ValueError(f"gnss: time {dt:.0f} s from the almanac epoch is outside its validity (+/- {VALIDITY.days} days)")
        u = self.arg_lat0 + MEAN_MOTION * dt
        node = self.node0 + (NODE_RATE - OMEGA_EARTH) * dt
        cu, su = np.cos(u), np.sin(u)
        cn, sn = np.cos(node), np.sin(node)
        ci, si = np.cos(INCLINATION), np.sin(INCLINATION)
        return RADIUS * np.stack([cu * cn - su * ci * sn, cu * sn + su * ci * cn, su * si], axis=1)
