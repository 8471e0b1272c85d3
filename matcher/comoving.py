"""Co-moving points: returns from an object that keeps station with the sensor (a chase boat, a
boat alongside), which a scan-to-scan matcher would take for a static world that says "no motion".

Two hypotheses per point of the new scan, against the reference scan's planes: it is static (moved
by the motion prior, it lies on a reference plane) or it moves with the sensor (unmoved, it lies on
one). Where the prior predicts a motion well above the range noise, a point that fits "unmoved"
within a quarter of that motion and better than "static" by half of it moves with the sensor.
Surfaces parallel to the motion fit both equally and are kept (they say nothing about it). The
points found are remembered, so that the next scan's returns from the same object are dropped
too, although the screened reference no longer holds them, unless they fit the static world (or a
patch of wall once dropped would stay dropped, moving with the sensor, and spread scan by scan).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from matcher.motion import transform
from matcher.planarity import voxel_keys

MIN_MOTION_M = 0.05
"""Below this predicted motion per scan the two hypotheses cannot be told apart: nothing is dropped."""


def plane_distance(q: np.ndarray, xyz: np.ndarray, normals: np.ndarray, nearest, max_m: float) -> np.ndarray:
    """|distance| of each point q to the plane of its nearest reference point (inf without one within max_m)."""
    dist, idx = nearest.query(q, distance_upper_bound=max_m)
    out = np.full(len(q), np.inf)
    found = np.isfinite(dist)
    out[found] = np.abs(np.einsum("ij,ij->i", normals[idx[found]], q[found] - xyz[idx[found]]))
    return out


def moving_with_sensor(
    xyz: np.ndarray,
    prior: np.ndarray,
    ref_xyz: np.ndarray,
    ref_normals: np.ndarray,
    ref_nearest,
    ref_moving: np.ndarray,
    max_m: float,
    recall_m: float,
) -> np.ndarray:
    """Mask of the points of `xyz` (new scan, its frame) that move with the sensor, given the motion
    `prior` (4x4, new frame in the reference's), the reference's points, normals and nearest-point
    query, and the points found moving in the reference (its frame): a point within recall_m of one
    is taken as the same object unless it fits the static world."""
    motion = float(np.linalg.norm(prior[:3, 3]))
    if motion < MIN_MOTION_M or len(xyz) == 0:
        return np.zeros(len(xyz), dtype=bool)
    # judged on one point per cell of recall_m (the matcher's voxel), the verdict shared by the cell's points
    _, first, cell = np.unique(voxel_keys(xyz, recall_m), return_index=True, return_inverse=True)
    q = xyz[first]
    static = plane_distance(transform(q, prior[:3, :3], prior[:3, 3]), ref_xyz, ref_normals, ref_nearest, max_m)
    unmoved = plane_distance(q, ref_xyz, ref_normals, ref_nearest, max_m)
    close = unmoved < 0.25 * motion
    moving = close & (static - np.where(close, unmoved, 0.0) > 0.5 * motion)
    if len(ref_moving):
        recalled = np.isfinite(cKDTree(ref_moving).query(q, distance_upper_bound=recall_m)[0])
        moving |= recalled & ~(static < 0.25 * motion)
    return moving[cell.reshape(-1)]
