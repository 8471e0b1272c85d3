"""A bag's compass, as xsens_mti_driver records an AHRS, read into the HeadingEvents a run feeds its estimators.

The unit's heading, roll and pitch come from its geometry_msgs/QuaternionStamped orientation (ENU, the driver's
/filter/quaternion), the field from its sensor_msgs/MagneticField (/imu/mag, tesla) with the same header stamp: the
field levelled with the unit's own roll and pitch gives the dip a filter checks for steel nearby
(sim.magnetic_compass.dip_deg), as in a run. The heading's accuracy is the scenario's [compass] heading_sigma_deg
(neither message carries it). Read only when the scenario feeds an estimator the compass and the bag has exactly
one topic of each type; else the replay runs without a compass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from riverbench.samples import HeadingSample
from scenarios.pipeline.inertial import HeadingEvent
from sim.magnetic_compass import dip_deg, levelled

ATTITUDE = "geometry_msgs/msg/QuaternionStamped"
MAGNETIC = "sensor_msgs/msg/MagneticField"


@dataclass(frozen=True)
class CompassTopics:
    """The bag's AHRS topics and the heading accuracy to state with each of its headings."""

    attitude: str
    field: str
    sigma: float
    """The scenario's [compass] heading accuracy, rad."""

    @property
    def source(self) -> str:
        return f"{self.attitude} and {self.field}"


@dataclass
class CompassPairing:
    """Joins each orientation with the field of the same header stamp into one HeadingEvent (either may come first)."""

    sigma: float
    """The unit's stated heading accuracy, rad."""

    def __post_init__(self) -> None:
        self._attitudes: dict[int, tuple[float, float, float]] = {}
        self._fields: dict[int, np.ndarray] = {}

    def attitude(self, ns: int, stamp: float, msg) -> HeadingEvent | None:
        """Take one QuaternionStamped; the heading when its field has come."""
        q = msg.quaternion
        yaw, pitch, roll = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_euler("ZYX")
        self._attitudes[ns] = (float(roll), float(pitch), float(yaw))
        return self._joined(ns, stamp)

    def field(self, ns: int, stamp: float, msg) -> HeadingEvent | None:
        """Take one MagneticField (tesla); the heading when its orientation has come."""
        b = msg.magnetic_field
        self._fields[ns] = np.array([b.x, b.y, b.z], dtype=float) * 1e6
        return self._joined(ns, stamp)

    def _joined(self, ns: int, stamp: float) -> HeadingEvent | None:
        if ns not in self._attitudes or ns not in self._fields:
            return None
        (roll, pitch, yaw), field_ut = self._attitudes.pop(ns), self._fields.pop(ns)
        dip = float(dip_deg(levelled(field_ut[None, :], np.array([roll]), np.array([pitch])))[0])
        return HeadingEvent(stamp, HeadingSample(stamp, yaw, field_ut, self.sigma, dip, roll, pitch), math.nan)
