"""What an IMU and a magnetic compass hand a filter: plain data, as a real boat's drivers log it.

The simulator (sim) produces these and the filters (fusion) consume them, so neither imports the
other and the same filters run on a real boat's logs. Frames follow REP-103: body = base_link
(x forward, y left, z up); yaw in the world ENU frame, from east, counter-clockwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ImuSamples:
    """A batch of IMU samples in time order (a driver's burst, e.g. one LiDAR revolution's worth).

    stamp: (N,) seconds; gyro: (N, 3) angular rate in rad/s and accel: (N, 3) specific force in
    m/s^2, both in the IMU's body frame (gravity reads +g up at rest, as sensor_msgs/Imu carries it).
    gyro_noise / accel_noise: the datasheet's white-noise densities (rad/s/sqrt(Hz), m/s^2/sqrt(Hz)),
    which a driver's covariance fields and a filter's process noise use.
    """

    stamp: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    gyro_noise: float
    accel_noise: float

    def __post_init__(self) -> None:
        n = len(self.stamp)
        if np.shape(self.gyro) != (n, 3) or np.shape(self.accel) != (n, 3):
            raise ValueError(f"imu samples: gyro and accel must be ({n}, 3), got {np.shape(self.gyro)} and {np.shape(self.accel)}")

    def __len__(self) -> int:
        return len(self.stamp)


@dataclass(frozen=True)
class HeadingSample:
    """One compass output: the magnetometer's field in the body frame and the heading the unit derived from it.

    stamp: seconds; yaw: heading in rad in the world ENU frame (from east, counter-clockwise; true,
    the declination applied); field_ut: (3,) measured field in base_link, microtesla; sigma: the
    unit's stated heading accuracy (rad, 1-sigma). field_norm_ut and dip_deg describe the field the
    heading came from: a filter compares them with the undisturbed field to detect steel nearby.
    """

    stamp: float
    yaw: float
    field_ut: np.ndarray
    sigma: float
    dip_deg: float
    roll: float = 0.0
    """The unit's own roll estimate it levelled the field with, rad (an AHRS publishes it with the heading)."""
    pitch: float = 0.0
    """The unit's own pitch estimate, rad."""

    @property
    def field_norm_ut(self) -> float:
        return float(np.linalg.norm(self.field_ut))

    @property
    def finite(self) -> bool:
        return math.isfinite(self.stamp) and math.isfinite(self.yaw) and bool(np.all(np.isfinite(self.field_ut)))
