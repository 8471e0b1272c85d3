"""How far a receiver's output strays from its own velocity over ground where nothing is wrong, learned from the fixes
its host trusted: the noise of the consistency monitor's walk test.

A receiver's displacement over a lag less its velocity over ground (RMC speed and course, from the carrier's range rates:
Doppler) integrated over the same lag is the change of its output's error plus the Doppler's error. Over fixes the host
trusts it is what the receiver's filter and its slowly varying range errors make of a second or so: on charles_river
the simulated receiver's clean residual over 1 s is 0.13 m per axis (from its true errors) and grows about as the
square root of the lag (0.22 m over 4 s), while the host's error model, HDOP x UERE correlated over gps_correlation_s,
bounds any receiver and gives 0.48 m over 1 s and 0.83 m over 4 s. Judged on that model a walk-back's tail turning at
0.9 m/s passed the walk test (the full quickstart, seed 0, 1790.0 s: 1.8 m against the Doppler over 4 s, at 4.5 under the
gate's 4.6) and took the ekf 2.2 -> 4.5 m off. Like the cn0 monitor's C/N0 template, the spread is a property of the
receiver and its filter, learned from its own output rather than configured: the robust spread (median absolute
deviation, cn0's MAD_TO_SIGMA) per axis of the residual over `lag_s` between trusted fixes, scaled to a lag L by
sqrt(L / lag_s) (a random walk; where the error changes more like white noise, as beside the quays, that overstates long
lags, on the safe side of the test).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Sequence

import numpy as np

from fusion.monitors.cn0 import MAD_TO_SIGMA
from fusion.observation import FixObservation

RESOLUTION_M = 0.02
"""Floor of the learned spread, m: a position reported in NMEA GGA to 1e-5 arc minute is quantised to 1.9 cm of latitude."""


class TrackNoise:
    """The receiver's clean displacement residual against its own velocity over ground, learned online."""

    def __init__(self, lag_s: float = 1.0, samples: int = 600, min_samples: int = 50) -> None:
        self.lag_s, self.min_samples = lag_s, min_samples
        self._residuals: deque[np.ndarray] = deque(maxlen=samples)  # per lag_s, east and north

    @property
    def sigma_m(self) -> np.ndarray | None:
        """Per-axis (east, north) spread of a residual over lag_s, m: the normal-consistent median absolute deviation of
        the learned ones, at least RESOLUTION_M (None until min_samples). Robust, because the host trusts the first fixes
        of a fault before its monitor sees it (a ramp's onset at metres a second): four such among 99 clean ones tripled
        the root mean square (tests/test_monitors.py, the walk-back's tail)."""
        if len(self._residuals) < self.min_samples:
            return None
        r = np.asarray(self._residuals)
        return np.maximum(MAD_TO_SIGMA * np.median(np.abs(r - np.median(r, axis=0)), axis=0), RESOLUTION_M)

    def noise_of(self, sigma: np.ndarray, a: FixObservation, b: FixObservation) -> np.ndarray:
        """2x2 noise of the receiver's displacement from fix a to fix b less its velocity's integral, for the learned
        per-axis spread `sigma` (sigma_m, taken once for the many lags of one fix)."""
        return np.diag(sigma**2) * (b.stamp - a.stamp) / self.lag_s

    def learn(self, trusted: Sequence[FixObservation]) -> None:
        """Learn from consecutive fixes the host trusted, the newest last: the residual from the newest fix at least lag_s
        before the last one to the last, when every fix between gives a velocity (trapezoids between fixes)."""
        last = trusted[-1]
        start = next((i for i in range(len(trusted) - 2, -1, -1) if trusted[i].stamp <= last.stamp - self.lag_s), None)
        if start is None:
            return
        velocities = [f.ground_velocity for f in trusted[start:]]
        if any(v is None for v in velocities):
            return
        stamps = np.array([f.stamp for f in trusted[start:]])
        v = np.asarray(velocities, dtype=float)
        moved = (0.5 * (v[1:] + v[:-1]) * np.diff(stamps)[:, None]).sum(axis=0)
        dt = last.stamp - trusted[start].stamp
        self._residuals.append((last.xy - trusted[start].xy - moved) * math.sqrt(self.lag_s / dt))
