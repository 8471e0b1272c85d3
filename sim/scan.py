"""The Scan: one HDL-32E revolution as the sensor driver reports it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

POINT_DTYPE = np.dtype(
    [
        ("x", np.float32),
        ("y", np.float32),
        ("z", np.float32),
        ("intensity", np.float32),
        ("ring", np.uint16),
        ("time", np.float32),
        ("label", np.uint16),
    ]
)
"""Per point: x, y, z in the lidar frame at the point's firing time (metres); intensity (0..255
scale like the sensor's calibrated reflectivity byte); ring = laser id (firing order); time =
seconds since `Scan.stamp`; label = index of the world part hit, or, for a label >= len(world.parts),
mover label - len(world.parts) of the scene's traffic (sim.scene.Scene; simulation ground truth only)."""


@dataclass
class Scan:
    """One revolution that started at `stamp` (seconds since scenario start)."""

    stamp: float
    points: np.ndarray

    def __post_init__(self) -> None:
        if self.points.dtype != POINT_DTYPE:
            raise TypeError(f"Scan.points must have dtype {POINT_DTYPE}, got {self.points.dtype}")

    def __len__(self) -> int:
        return len(self.points)

    @property
    def xyz(self) -> np.ndarray:
        """(N, 3) float64 coordinates in the lidar frame."""
        return np.stack([self.points["x"], self.points["y"], self.points["z"]], axis=1).astype(np.float64)

    @classmethod
    def empty(cls, stamp: float) -> Scan:
        return cls(stamp=stamp, points=np.zeros(0, dtype=POINT_DTYPE))
