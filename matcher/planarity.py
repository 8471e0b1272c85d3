"""Planarity: whether a point's surroundings span a surface, so that a normal estimated there means something.

A LiDAR ring crossing a surface at a grazing angle (a deck overhead, a far wall) leaves points on one
line; a normal fitted to a line is free to turn about it, and at a line point the point-to-plane
"distance" says as much about where the sensor's ring fell as about the surface. Counted as plane
constraints such points fake information along the surface: the ring moves with the sensor, so
they favour "no motion". Planarity is the middle over the largest eigenvalue of the covariance of
the raw points in a coarse voxel around the point: about 0 on a line, up to 1 on an evenly
covered surface (a wall seen by several rings).
"""

from __future__ import annotations

import numpy as np

_MIN_POINTS = 5


def voxel_keys(xyz: np.ndarray, voxel_m: float) -> np.ndarray:
    """One int64 key per point for its voxel (21 bits per axis, as small_gicp's voxel grid)."""
    ijk = np.floor(xyz / voxel_m).astype(np.int64) & 0x1FFFFF
    return (ijk[:, 0] << 42) | (ijk[:, 1] << 21) | ijk[:, 2]


def planarity(raw: np.ndarray, query: np.ndarray, voxel_m: float) -> np.ndarray:
    """(len(query),) lambda2 / lambda1 of the covariance of the `raw` points (N, 3) in each query
    point's voxel of side voxel_m (0 where the voxel holds fewer than 5 raw points)."""
    keys, inverse = np.unique(voxel_keys(raw, voxel_m), return_inverse=True)
    value = _voxel_planarity(raw, inverse, len(keys))
    q = voxel_keys(query, voxel_m)
    at = np.clip(np.searchsorted(keys, q), 0, len(keys) - 1)
    return np.where(keys[at] == q, value[at], 0.0)


def _voxel_planarity(raw: np.ndarray, inverse: np.ndarray, m: int) -> np.ndarray:
    """(m,) lambda2 / lambda1 of the covariance of the `raw` points in each of m voxels (`inverse`: each
    point's), 0 where a voxel holds fewer than 5. The sums are taken column by column (contiguous
    (N,) arrays, the same sums as of the (N, 3) rows) and only the voxels with 5 points or more are
    decomposed: about a third of a dense scan's, and eigvalsh works on each matrix on its own."""
    count = np.bincount(inverse, minlength=m)
    n = np.maximum(count, 1).astype(float)
    d = [raw[:, i] - (np.bincount(inverse, raw[:, i], m) / n)[inverse] for i in range(3)]
    full = count >= _MIN_POINTS
    cov = np.empty((int(full.sum()), 3, 3))
    for i in range(3):
        for j in range(i, 3):
            cov[:, i, j] = cov[:, j, i] = np.bincount(inverse, d[i] * d[j], m)[full]
    lam = np.linalg.eigvalsh(cov)  # ascending
    value = np.zeros(m)
    value[full] = np.where(lam[:, 2] > 0, lam[:, 1] / np.where(lam[:, 2] > 0, lam[:, 2], 1.0), 0.0)
    return value
