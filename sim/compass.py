"""The vessel's heading sensor (AHRS: compass and gyro): true yaw and yaw rate plus white noise, as an autopilot reads them.

Every ASV steers its heading on such a sensor, not on GPS course or a position estimate; the
closed loop gives the autopilot this heading by default, and the position of the estimator under test.
"""

from __future__ import annotations

import math

import numpy as np

from riverbench.angles import wrap_angle
from riverbench.rng import stream


class Compass:
    """`read(trajectory, t)`: heading (rad from east, CCW) and yaw rate (rad/s) with seeded Gaussian noise."""

    def __init__(self, sigma_deg: float = 1.0, rate_sigma_dps: float = 0.3, seed: int = 0):
        self.sigma, self.rate_sigma = math.radians(sigma_deg), math.radians(rate_sigma_dps)
        self._rng = stream(seed, "sim.compass")

    def read(self, trajectory, t: float, since: float, dt: float = 0.01) -> tuple[float, float]:
        """At time t of a trajectory known from `since` on (the rate is differenced over the last dt seconds)."""
        dt = min(dt, t - since)
        before, now = trajectory.poses(np.array([t - dt, t]))
        yaw = math.atan2(now[1, 0], now[0, 0])
        step = wrap_angle(yaw - math.atan2(before[1, 0], before[0, 0]))
        rate = step / dt if dt > 0 else 0.0
        noise = self._rng.standard_normal(2)
        return yaw + self.sigma * float(noise[0]), rate + self.rate_sigma * float(noise[1])


def with_heading(pose: np.ndarray, yaw: float) -> np.ndarray:
    """`pose` (4x4) with its rotation replaced by a level one at `yaw` (NaN stays NaN)."""
    out = np.array(pose, dtype=float)
    c, s = math.cos(yaw), math.sin(yaw)
    out[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    return out
