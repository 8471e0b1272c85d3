"""What the LiDAR has seen stand up around the vessel, kept as a height map, to tell which satellites' lines of sight it blocks.

A satellite whose direct signal is blocked reaches the antenna only by reflection (NLOS), if at all, and its
pseudorange then carries the extra path. Beside a quay or a canal wall the blocking structure is right there in the
scans: a satellite at azimuth az and elevation el is blocked when some return along az, at horizontal distance r from
the antenna, stands higher than the antenna plus r tan(el) (shadow matching with a LiDAR instead of a city model:
Groves 2011, J. Navigation 64(3):417-430; Wen, Zhang and Hsu 2019, NAVIGATION 66(4), NLOS corrected with a
LiDAR's point cloud). An HDL-32E's top beam points 10.67 deg up, so one scan sees a wall's top only from more than
5.3 wall heights away: the map therefore keeps each cell's highest return over the last `horizon_s` seconds,
placed in the world with the filter's pose, and a wall seen whole from afar stays known as the vessel comes alongside.

Cells the LiDAR never saw (open water beyond its range, the sky above its top beam) block nothing: the map confirms a
blockage, it never invents one.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field


class ObstacleMapParams(BaseModel):
    """Parameters of the LiDAR height map that tests satellites' lines of sight."""

    model_config = ConfigDict(extra="forbid")

    cell_m: float = Field(1.0, gt=0, le=10, description="grid cell edge, m [1: a quay's or wall's face is one cell thick]")
    size_m: float = Field(
        400.0,
        gt=0,
        description="edge of the square map kept around the vessel, m [400: twice the 100 m HDL-32E's range, Velodyne "
        "HDL-32E datasheet, with room for what it saw on the way]",
    )
    horizon_s: float = Field(120.0, gt=0, description="a cell forgets its height this long after it was last seen, s [120: 240 m of travel at 2 m/s]")
    min_range_m: float = Field(
        3.0, ge=0, description="returns closer than this to the lidar are the vessel itself and block nothing, m [3: a WAM-V's half length]"
    )
    max_range_m: float = Field(
        150.0, gt=0, description="a line of sight is tested this far from the antenna, m [150: beyond the LiDAR's range nothing is mapped]"
    )
    margin_m: float = Field(
        0.5,
        ge=0,
        description="a return blocks a line of sight only when it stands this much above it, m [0.5: the returns' own "
        "scatter (2 cm ranging, 0.3 deg beam divergence at 50 m) and the filter's height error]",
    )


class ObstacleMap:
    """The highest LiDAR return per world cell around the vessel over the last horizon_s; `blocked` tests a satellite."""

    def __init__(self, params: ObstacleMapParams) -> None:
        self.params = params
        self.n = int(math.ceil(params.size_m / params.cell_m))
        self._height = np.full((self.n, self.n), -np.inf)
        self._seen = np.full((self.n, self.n), -np.inf)
        self._origin: np.ndarray | None = None  # world (x, y) of cell [0, 0]'s corner

    @property
    def empty(self) -> bool:
        """Nothing placed yet (no scan with a finite pose)."""
        return self._origin is None

    def add(self, stamp: float, pose: np.ndarray, points: np.ndarray) -> None:
        """Place one scan's points (N, 3, base_link) in the world with pose (4x4 world<-base_link at the scan), leaving out
        the vessel itself (within min_range_m) and non-finite points."""
        points = np.asarray(points, dtype=float)
        if not np.all(np.isfinite(pose)) or not len(points):
            return
        keep = np.all(np.isfinite(points), axis=1)
        keep[keep] = np.hypot(points[keep, 0], points[keep, 1]) >= self.params.min_range_m
        points = points[keep]
        self._centre_on(pose[:2, 3])
        assert self._origin is not None
        world = points @ pose[:3, :3].T + pose[:3, 3]
        index = np.floor((world[:, :2] - self._origin) / self.params.cell_m).astype(np.int64)
        inside = np.all((index >= 0) & (index < self.n), axis=1)
        flat = index[inside, 0] * self.n + index[inside, 1]
        height, seen = self._height.reshape(-1), self._seen.reshape(-1)
        height[flat[seen[flat] < stamp - self.params.horizon_s]] = -np.inf  # a cell seen again after the horizon starts over
        np.maximum.at(height, flat, world[inside, 2])
        seen[flat] = stamp

    def blocked(self, stamp: float, antenna: np.ndarray, az_deg: np.ndarray, el_deg: np.ndarray) -> np.ndarray:
        """Per satellite (azimuth clockwise from north, elevation, deg): does a return seen within horizon_s stand above
        the line from the antenna (world x, y, z) towards it? False where the map saw nothing (module docstring)."""
        az, el = np.radians(np.asarray(az_deg, dtype=float)), np.radians(np.asarray(el_deg, dtype=float))
        out = np.zeros(az.shape, dtype=bool)
        judged = np.isfinite(az) & np.isfinite(el)
        if self._origin is None or not np.all(np.isfinite(antenna)) or not judged.any():
            return out
        out[judged] = self._blocked(stamp, antenna, az[judged], el[judged])
        return out

    def _blocked(self, stamp: float, antenna: np.ndarray, az: np.ndarray, el: np.ndarray) -> np.ndarray:
        """blocked() for finite azimuths and elevations in radians."""
        assert self._origin is not None
        p = self.params
        r = np.arange(p.min_range_m, p.max_range_m, 0.5 * p.cell_m)
        east, north = np.sin(az)[:, None] * r, np.cos(az)[:, None] * r
        i = np.floor((antenna[0] + east - self._origin[0]) / p.cell_m).astype(np.int64)
        j = np.floor((antenna[1] + north - self._origin[1]) / p.cell_m).astype(np.int64)
        inside = (i >= 0) & (i < self.n) & (j >= 0) & (j < self.n)
        i, j = np.where(inside, i, 0), np.where(inside, j, 0)
        fresh = inside & (self._seen[i, j] >= stamp - p.horizon_s)
        line = antenna[2] + r * np.tan(el)[:, None] + p.margin_m
        return np.any(fresh & (self._height[i, j] > line), axis=1)

    def _centre_on(self, xy: np.ndarray) -> None:
        """Keep the vessel within the middle half of the map, scrolling what was seen with it."""
        half = 0.5 * self.n * self.params.cell_m
        if self._origin is None:
            self._origin = np.floor((xy - half) / self.params.cell_m) * self.params.cell_m
            return
        offset = xy - (self._origin + half)
        if np.all(np.abs(offset) <= 0.5 * half):
            return
        shift = np.round(offset / self.params.cell_m).astype(np.int64)
        self._origin = self._origin + shift * self.params.cell_m
        self._height = _shifted(self._height, shift, -np.inf)
        self._seen = _shifted(self._seen, shift, -np.inf)


def _shifted(grid: np.ndarray, shift: np.ndarray, fill: float) -> np.ndarray:
    """grid moved by -shift cells (what was at shift is now at 0), `fill` where nothing was."""
    out = np.full_like(grid, fill)
    n = grid.shape[0]
    si, sj = int(shift[0]), int(shift[1])
    if abs(si) >= n or abs(sj) >= n:
        return out
    src_i, dst_i = slice(max(si, 0), n + min(si, 0)), slice(max(-si, 0), n + min(-si, 0))
    src_j, dst_j = slice(max(sj, 0), n + min(sj, 0)), slice(max(-sj, 0), n + min(-sj, 0))
    out[dst_i, dst_j] = grid[src_i, src_j]
    return out
