"""The autopilot's heading sensor (an AHRS: a magnetic compass unit and a gyro), as the autopilot reads them.

Every ASV steers its heading on such a sensor, not on GPS course or a position estimate; the closed loop
gives the autopilot this heading by default, and the position of the estimator under test. The heading is
a magnetic compass unit's (sim.magnetic_compass, with the scenario's [compass] figures or the MTi
defaults): its own unit with its own iron residuals and noise, and disturbed by the world's steel like
the estimators' compass, so an autopilot under a steel bridge steers on a wrong heading as a real one
does. The yaw rate is the true one differenced over the last 10 ms plus white gyro noise.
"""

from __future__ import annotations

import math

import numpy as np

from riverbench.angles import wrap_angle
from riverbench.rng import stream
from sim.magnetic_compass import CompassConfig, MagneticCompass
from sim.magnetism import SteelField


class Ahrs:
    """`read(trajectory, t, since)`: the compass unit's heading (rad from east, CCW, true) and a gyro's yaw rate (rad/s)."""

    def __init__(self, world, compass: CompassConfig | None = None, rate_sigma_dps: float = 0.3, seed: int = 0, steel: SteelField | None = None):
        """`steel`: the world's steel dipoles when another compass already computed them (the same for every unit)."""
        rng = stream(seed, "sim.compass")
        self.compass = MagneticCompass(world, compass, seed=int(rng.integers(2**31)), steel=steel)
        self.rate_sigma = math.radians(rate_sigma_dps)
        self._rng = rng

    def read(self, trajectory, t: float, since: float, dt: float = 0.01) -> tuple[float, float]:
        """At time t of a trajectory known from `since` on (the rate is differenced over the last dt seconds)."""
        (sample,) = self.compass.read(trajectory, np.array([t]))
        dt = min(dt, t - since)
        before, now = trajectory.poses(np.array([t - dt, t]))
        step = wrap_angle(math.atan2(now[1, 0], now[0, 0]) - math.atan2(before[1, 0], before[0, 0]))
        rate = step / dt if dt > 0 else 0.0
        return sample.yaw, rate + self.rate_sigma * float(self._rng.standard_normal())


def with_heading(pose: np.ndarray, yaw: float) -> np.ndarray:
    """`pose` (4x4) with its rotation replaced by a level one at `yaw` (NaN stays NaN)."""
    out = np.array(pose, dtype=float)
    c, s = math.cos(yaw), math.sin(yaw)
    out[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    return out
