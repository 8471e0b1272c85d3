"""The compass's heading against the gyro's: steel nearby shows as the two disagreeing beyond what either can err by.

The offset compass heading - gyro integral is, for an undisturbed compass, a straight line whose slope is the gyro's
bias, plus the compass's white scatter (its tilt error through the dip, the magnetometer's noise) and the residual
hard- and soft-iron error, which changes with the heading turned through. Near steel the field, and the heading with
it, bends away as the boat closes in (sim.magnetism: a dipole field growing as 1/r^3), gently enough that an
innovation gate at 3 sigma of the compass's stated 1 deg lets 1-3 deg through; here the bend leaves the line.

The line is fitted to the trusted headings of the last fit_s (older than average_s, so a heading is never compared
with itself); each heading's offset, averaged over the last average_s, is compared with the line's value, within the
fit's own prediction error (its residual scatter is the compass's), the white scatter of the average, the iron
error over the headings between the fit's and this one, and the gyro's angle random walk and bias wander from the
fit's centre.
The filter's bias estimate is not used (a compass it has already taken in would have moved it). While headings are
refused the fit is frozen and the budget grows with the distance from it, so a disturbance lasting longer than the
gyro can vouch for is accepted again: beyond that the two cannot be told apart.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from riverbench.angles import wrap_angle


@dataclass(frozen=True)
class CompassGyroBudget:
    """What the check allows: the share of the heading turned through that the residual iron error may change the heading
    by (1 sigma), the gyro's angle random walk (rad/s/sqrt(Hz)) and bias random walk (rad/s/sqrt(s)), the fit's span and
    the averaging time (s), the fewest trusted headings a fit needs, and the gate in sigmas."""

    iron_share: float
    bias_walk: float
    fit_s: float
    average_s: float
    min_headings: int
    z: float


class CompassGyroCheck:
    """`check(stamp, compass_yaw, gyro_yaw, arw)` per compass heading, in time order: True when it agrees with the gyro
    (trusted; also while too few headings are trusted for a fit), False when it is refused as disturbed."""

    def __init__(self, budget: CompassGyroBudget) -> None:
        self.budget = budget
        self._recent: deque[tuple[float, float, float]] = deque()  # every heading of the last average_s: (stamp, offset, heading)
        self._pending: deque[tuple[float, float, float]] = deque()  # trusted headings not yet average_s old
        self._fit: deque[tuple[float, float, float]] = deque()  # trusted headings in the fit
        self._sums = np.zeros(8)  # n, sum t, o, psi, t^2, t o, o^2, psi^2 over the fit (t from the first stamp)
        self._anchor: float | None = None  # offsets are unwrapped about it
        self._t0: float | None = None
        self.disagreement = 0.0
        """The latest averaged offset's distance from the fitted line, rad."""
        self.limit = math.inf
        """The threshold it was held to, rad."""

    def check(self, stamp: float, compass_yaw: float, gyro_yaw: float, arw: float) -> bool:
        """A heading `compass_yaw` (rad) at `stamp`, the gyro's integrated yaw `gyro_yaw` then (rad, not wrapped, the
        raw rates less the Earth's: no bias taken off) and its white noise density `arw` (rad/s/sqrt(Hz))."""
        b = self.budget
        raw = wrap_angle(compass_yaw - gyro_yaw)
        if self._anchor is None or self._t0 is None:
            self._anchor, self._t0 = raw, stamp
        t = stamp - self._t0
        offset = self._anchor + wrap_angle(raw - self._anchor)
        sample = (t, offset, offset + gyro_yaw)  # the heading: the compass's, unwrapped along the gyro
        self._recent.append(sample)
        while self._recent[0][0] < t - b.average_s:
            self._recent.popleft()
        while self._pending and self._pending[0][0] < t - b.average_s:
            self._add(self._pending.popleft(), 1.0)
        trusted = self._agrees(arw)
        if trusted:
            self._pending.append(sample)
            self._anchor = offset
            while self._fit and self._fit[0][0] < t - b.fit_s - b.average_s:
                self._add(self._fit[0], -1.0)
                self._fit.popleft()
        return trusted

    def _add(self, sample: tuple[float, float, float], sign: float) -> None:
        t, o, psi = sample
        self._sums += sign * np.array([1.0, t, o, psi, t * t, t * o, o * o, psi * psi])
        if sign > 0:
            self._fit.append(sample)

    def _agrees(self, arw: float) -> bool:
        b = self.budget
        n, st, so, spsi, stt, sto, soo, spp = self._sums
        if n < b.min_headings:
            self.disagreement, self.limit = 0.0, math.inf
            return True
        t_mean, o_mean, psi_mean = st / n, so / n, spsi / n
        sxx, sxo, syy = stt - n * t_mean**2, sto - n * t_mean * o_mean, soo - n * o_mean**2
        slope = sxo / sxx if sxx > 0 else 0.0
        scatter = max(syy - slope * sxo, 0.0) / max(n - 2.0, 1.0)
        m = len(self._recent)
        t_r = sum(r[0] for r in self._recent) / m
        o_r = sum(r[1] for r in self._recent) / m
        psi_r = sum(r[2] for r in self._recent) / m
        tau = max(t_r - t_mean, 0.0)
        turned = math.sqrt(max(spp / n - 2.0 * psi_r * psi_mean + psi_r**2, 0.0))  # rms distance of the fit's headings from this one
        d = o_r - (o_mean + slope * (t_r - t_mean))
        var = (
            scatter / m  # the average's white scatter
            + scatter * (1.0 / n + (tau**2 / sxx if sxx > 0 else 0.0))  # the line's prediction error
            + (b.iron_share * turned) ** 2  # iron error between the fit's headings and this one
            + arw**2 * tau  # the gyro's angle random walk
            + b.bias_walk**2 * tau**3 / 3.0  # its bias wandering off the fitted slope
        )
        self.disagreement, self.limit = float(d), b.z * math.sqrt(var)
        return bool(abs(d) <= self.limit)


__all__ = ["CompassGyroBudget", "CompassGyroCheck"]
