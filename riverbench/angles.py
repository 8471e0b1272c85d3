"""Angle wrapping, one formula each for radians and degrees, so that every package wraps alike, bit for bit.

Both are the floor modulo of Python and numpy (fmod, then the divisor added when the signs differ):
a float gives a float, a numpy array an array of its own dtype (the constants are Python floats, so
a float32 array stays float32).
"""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np

TWO_PI = 2.0 * math.pi
"""2 pi as a Python float (exactly 2.0 * math.pi == 2 * np.pi)."""

Angle = TypeVar("Angle", float, np.ndarray)


def wrap_angle(angle: Angle) -> Angle:
    """`angle` (radians, a float or an array) wrapped to [-pi, pi): (angle + pi) mod 2 pi - pi (rounding can
    give pi itself for an angle a hair below an odd multiple of -pi)."""
    return (angle + math.pi) % TWO_PI - math.pi


def wrap_deg(angle: Angle) -> Angle:
    """`angle` (degrees, a float or an array) wrapped to [-180, 180): (angle + 180) mod 360 - 180 (rounding
    can give 180 itself for an angle a hair below an odd multiple of -180)."""
    return (angle + 180.0) % 360.0 - 180.0


__all__ = ["TWO_PI", "wrap_angle", "wrap_deg"]
