"""Cloud: the usable part of a scan (finite points in a range band) as float64 arrays."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.scan import Scan


@dataclass(frozen=True)
class Cloud:
    """Finite points of one scan: xyz (N, 3) in the lidar frame at each firing time, time (N,) s."""

    stamp: float
    xyz: np.ndarray
    time: np.ndarray
    n_raw: int

    def __len__(self) -> int:
        return len(self.xyz)

    @classmethod
    def from_scan(cls, scan: Scan, min_range_m: float, max_range_m: float) -> Cloud:
        """Keep points with finite x, y, z and time whose range lies in [min_range_m, max_range_m].

        Only geometry and firing time are read: never the simulator's `label` field."""
        pts = scan.points
        xyz = np.stack([pts["x"], pts["y"], pts["z"]], axis=1).astype(np.float64)
        time = pts["time"].astype(np.float64)
        rng = np.linalg.norm(xyz, axis=1)
        keep = np.isfinite(xyz).all(axis=1) & np.isfinite(time) & (rng >= min_range_m) & (rng <= max_range_m)
        return cls(stamp=float(scan.stamp), xyz=xyz[keep], time=time[keep], n_raw=len(pts))
