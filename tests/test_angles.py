"""riverbench.angles: the one angle wrapping every package uses, bit for bit the inline formulas it replaced."""

from __future__ import annotations

import math

import numpy as np

import riverbench
from riverbench.angles import wrap_angle, wrap_deg

SPECIAL = [
    0.0,
    -0.0,
    math.pi,
    -math.pi,
    2 * math.pi,
    -3 * math.pi,
    1e-300,
    -5e-324,
    1e15,
    -1e15,
    math.nextafter(math.pi, 0.0),
    math.nextafter(-math.pi, 0.0),
    math.nextafter(-math.pi, -4.0),
]


def _values() -> np.ndarray:
    rng = np.random.default_rng(0)
    return np.concatenate([SPECIAL, rng.normal(0.0, 4.0, 20000), rng.integers(-40, 40, 2000) * math.pi])


def test_version_is_a_string():
    assert isinstance(riverbench.__version__, str) and riverbench.__version__


def test_wrap_angle_is_the_floor_modulo_formula_bit_for_bit():
    x = _values()
    for old in (lambda a: (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi, lambda a: (a + math.pi) % (2 * math.pi) - math.pi):
        assert np.array_equal(wrap_angle(x).view(np.int64), old(x).view(np.int64))
    for v in x[::50]:
        assert wrap_angle(float(v)) == (float(v) + math.pi) % (2.0 * math.pi) - math.pi
    assert type(wrap_angle(1.0)) is float
    assert wrap_angle(x.astype(np.float32)).dtype == np.float32


def test_wrapped_angles_lie_in_range():
    r = wrap_angle(_values())
    assert np.all(r >= -math.pi) and np.all(r <= math.pi)  # pi itself only by rounding, just below -pi
    d = wrap_deg(_values() * 57.3)
    assert np.all(d >= -180.0) and np.all(d <= 180.0)
    assert wrap_deg(190.0) == -170.0 and wrap_deg(-180.0) == -180.0 and wrap_angle(math.pi) == -math.pi


def test_wrap_deg_is_the_floor_modulo_formula_bit_for_bit():
    x = _values() * 57.3
    assert np.array_equal(wrap_deg(x).view(np.int64), ((x + 180.0) % 360.0 - 180.0).view(np.int64))
