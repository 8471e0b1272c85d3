"""The vessel's planar motion with its time derivatives: what a trajectory tells an inertial sensor model."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PlaneMotion:
    """The planar motion at times ts: position (N, 2), yaw (N,), world velocity (N, 2) and acceleration (N, 2), yaw rate (N,)."""

    xy: np.ndarray
    yaw: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    yaw_rate: np.ndarray
