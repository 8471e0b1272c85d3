"""ENU <-> ECEF <-> WGS-84 geodetic for one world origin, fast for one point at a time.

The receiver converts one position per epoch. pymap3d's vectorised routines cost ~0.1 ms per
scalar call (numpy overhead), a fifth of the receiver's budget, so the per-epoch ECEF->geodetic
step uses Heikkinen's exact closed form on Python floats; tests check it against pymap3d.
The local frame (rotation and origin) itself comes from pymap3d.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymap3d

WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_B = WGS84_A * (1.0 - WGS84_F)
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
WGS84_EP2 = (WGS84_A**2 - WGS84_B**2) / WGS84_B**2


def ecef_to_geodetic(x: float, y: float, z: float) -> tuple[float, float, float]:
    """WGS-84 (lat_deg, lon_deg, height_m) of an ECEF point, exact closed form (Heikkinen 1982)."""
    a, b, e2 = WGS84_A, WGS84_B, WGS84_E2
    p2 = x * x + y * y
    p = math.sqrt(p2)
    f = 54.0 * b * b * z * z
    g = p2 + (1.0 - e2) * z * z - e2 * (a * a - b * b)
    c = e2 * e2 * f * p2 / (g * g * g)
    s = (1.0 + c + math.sqrt(c * c + 2.0 * c)) ** (1.0 / 3.0)
    k = s + 1.0 + 1.0 / s
    pp = f / (3.0 * k * k * g * g)
    q = math.sqrt(1.0 + 2.0 * e2 * e2 * pp)
    r0 = -(pp * e2 * p) / (1.0 + q) + math.sqrt(0.5 * a * a * (1.0 + 1.0 / q) - pp * (1.0 - e2) * z * z / (q * (1.0 + q)) - 0.5 * pp * p2)
    u2 = (p - e2 * r0) ** 2
    big_u = math.sqrt(u2 + z * z)
    big_v = math.sqrt(u2 + (1.0 - e2) * z * z)
    z0 = b * b * z / (a * big_v)
    height = big_u * (1.0 - b * b / (a * big_v))
    return math.degrees(math.atan2(z + WGS84_EP2 * z0, p)), math.degrees(math.atan2(y, x)), height


@dataclass(frozen=True)
class LocalFrame:
    """The ENU tangent frame at a geodetic origin: ECEF origin and the ECEF->ENU rotation."""

    origin_ecef: np.ndarray
    ecef_to_enu: np.ndarray

    @classmethod
    def at(cls, lat_deg: float, lon_deg: float, alt_m: float) -> LocalFrame:
        origin = np.array(pymap3d.geodetic2ecef(lat_deg, lon_deg, alt_m))
        rotation = np.array([pymap3d.ecef2enuv(*axis, lat_deg, lon_deg) for axis in np.eye(3)]).T
        return cls(origin, rotation)

    def enu_of_ecef(self, ecef: np.ndarray) -> np.ndarray:
        """(N, 3) ENU coordinates of (N, 3) ECEF points."""
        return (ecef - self.origin_ecef) @ self.ecef_to_enu.T

    def geodetic_of_enu(self, enu: np.ndarray) -> tuple[float, float, float]:
        """(lat_deg, lon_deg, height_m) of one ENU point."""
        x, y, z = (self.origin_ecef + enu @ self.ecef_to_enu).tolist()
        return ecef_to_geodetic(x, y, z)
