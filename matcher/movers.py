"""Independently moving objects: boats under way in the scan, which a scan-to-scan matcher would take for the static world.

Between two revolutions a static surface moves only by the vessel's own motion; a boat under way moves by that and by
its own. Registered with the rest, its points pull the answer towards its motion: on busy_waterway's Harvard Bridge
stretch (seed 2) a cruiser oncoming under the span and a runabout overtaking turned gicp's chained yaw by 12 deg in 18 s
(0.1-0.2 deg a revolution, one sign), while without the traffic its yaw p95 was 0.9 deg. Sparse river scans make it worse:
a boat 20 m off can return as many points as the banks 80 m off.

The test is motion segmentation against the motion prior (the matcher's constant-velocity prediction from its last
match), so it runs only once there is one. Each cell of the new scan (one point per voxel) is moved by the prior and its
residual taken to the plane of its nearest reference point. The static world agrees with the prior to its error, a
centimetre or two a revolution (the last match's noise carried over 0.1 s; a hull's acceleration adds millimetres). The
scan is split into objects (cells connected within `link_m`); an object at most `max_extent_m` across whose cells are
explained by a horizontal translation of its own longer than `min_speed_mps` times the time between the scans is moving:
its points are dropped before registering. Only the directions the object's own surfaces measure count (a hull seen
side-on says nothing along its length). A pier or a buoy is static: its translation is the prior's error. The prior is
not fitted to the scan first: under a deck, where walls and deck leave the along-track motion to the piers, an oncoming
boat facing the same way outweighs them and a fit takes its motion for the vessel's (busy_waterway seed 2: 5.4 m/s
for 2.4). When more than half of the scan's cells would be dropped, the prior is more likely wrong than the world
moving, and nothing is. Nothing is remembered from scan to scan: the reference a mover was dropped from holds no
partner for its next returns, which then pair with nothing (ICP's correspondences end at max_correspondence_m) and are
judged again against the scan after; carrying the drop forward to whatever lay near a dropped object spread it over
static walls whenever a prior was briefly wrong.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from matcher.motion import transform
from matcher.planarity import voxel_keys

WATERLINE_QUANTILE = 0.005
"""The water surface in the scan: this low quantile of its heights (the banks, walls, piers and hulls all reach down to
it, and the few water returns lie on it)."""
FREEBOARD_M = 1.5
"""An object that moves on its own floats: its lowest point lies within this of the water surface (a hull's side seen
down to the waterline; a runabout's freeboard is under 1 m). A deck or a girder overhead, whose scan lines move with the
sensor and fake a translation against their own line-fitted normals, is no boat."""
BOAT_HEIGHT_M = 12.0
"""No boat stands higher above the water than this (the library's barge: a 7.5 m wheelhouse on its deck)."""
MAX_MOVING_SHARE = 0.5
"""When more of the scan's cells than this would be dropped, the prior is taken as wrong, not the world as moving."""
MIN_CELLS = 8
"""An object needs this many cells with a reference partner to be judged (fewer: too little to fit a translation)."""
MIN_INFORMATION = 4.0
"""A direction of an object's translation counts when its cells' normals, squared along it, sum to at least this: four
cells facing it, which measure the translation there to half the plane fits' noise; along a hull seen side-on they do not."""


@dataclass(frozen=True)
class MoverTest:
    """How objects moving on their own are told from the static world."""

    min_speed_mps: float
    link_m: float
    max_extent_m: float
    max_m: float


def moving_objects(
    xyz: np.ndarray,
    prior: np.ndarray,
    prior_cov: np.ndarray | None,
    dt: float,
    ref_xyz: np.ndarray,
    ref_normals: np.ndarray,
    ref_nearest,
    cell_m: float,
    test: MoverTest,
) -> np.ndarray:
    """Mask of the points of `xyz` (new scan, its frame) on objects moving on their own, given the motion `prior` (4x4,
    new frame in the reference's) and its translation's 3x3 covariance (None: unknown, nothing is judged) over `dt`
    seconds, the reference's points, normals and nearest-point query (partners within test.max_m)."""
    none = np.zeros(len(xyz), dtype=bool)
    if len(xyz) == 0 or dt <= 0.0 or prior_cov is None:
        return none
    _, first, cell = np.unique(voxel_keys(xyz, cell_m), return_index=True, return_inverse=True)
    q = transform(xyz[first], prior[:3, :3], prior[:3, 3])
    at = int(WATERLINE_QUANTILE * (len(q) - 1))
    waterline = np.partition(q[:, 2], at)[at]
    low = np.flatnonzero(q[:, 2] <= waterline + BOAT_HEIGHT_M)  # what stands higher is no boat's, and is not grouped
    objects, count = _objects(q[low], test.link_m)
    order = np.argsort(objects, kind="stable")
    starts = np.searchsorted(objects[order], np.arange(count))
    grouped = q[low][order]
    lo, hi = np.minimum.reduceat(grouped, starts), np.maximum.reduceat(grouped, starts)
    eligible = ((hi[:, :2] - lo[:, :2]).max(axis=1) <= test.max_extent_m) & (lo[:, 2] <= waterline + FREEBOARD_M)
    kept = eligible[objects]
    judged = low[kept]
    if not len(judged):
        return none
    q, objects = q[judged], objects[kept]  # only the cells of objects that could be boats are paired and judged
    dist, idx = ref_nearest.query(q, distance_upper_bound=test.max_m)
    paired = np.isfinite(dist)
    n = np.zeros_like(q)
    r = np.zeros(len(q))
    n[paired] = ref_normals[idx[paired]]
    r[paired] = np.einsum("ij,ij->i", n[paired], q[paired] - ref_xyz[idx[paired]])
    min_step = test.min_speed_mps * dt
    candidate = np.ones(len(q), dtype=bool)
    for _ in range(2):  # an object's translation, then again from the cells it explains: a pier a boat passes is not one
        steps = _translations(objects, count, n, r, paired & candidate, min_step, prior_cov[:2, :2])
        along = np.einsum("ij,ij->i", n[:, :2], steps[objects])
        explained = (np.abs(r - along) < np.abs(r)) & (np.abs(along) >= 0.5 * min_step)
        candidate = np.any(steps != 0.0, axis=1)[objects] & (explained | ~paired)
    if candidate.sum() > MAX_MOVING_SHARE * len(first):
        return none
    moving = np.zeros(len(first), dtype=bool)
    moving[judged] = candidate
    return moving[cell.reshape(-1)]


def _objects(q: np.ndarray, link_m: float) -> tuple[np.ndarray, int]:
    """Label (0-based) of each cell's object, cells connected through link_m voxels (26-neighbourhood), and the count."""
    ijk = np.floor(q / link_m).astype(np.int64)
    ijk -= ijk.min(axis=0)
    grid = np.zeros(tuple(ijk.max(axis=0) + 1), dtype=bool)
    grid[ijk[:, 0], ijk[:, 1], ijk[:, 2]] = True
    labels, count = ndimage.label(grid, structure=np.ones((3, 3, 3), dtype=bool))
    return labels[ijk[:, 0], ijk[:, 1], ijk[:, 2]] - 1, int(count)


def _translations(
    objects: np.ndarray, count: int, n: np.ndarray, r: np.ndarray, use: np.ndarray, min_step_m: float, prior_cov: np.ndarray
) -> np.ndarray:
    """(count, 2) the horizontal translation of each object found moving, zeros for the rest: an object is moving when
    its `use`d cells are explained by a translation of its own, along a direction they measure, longer than min_step_m
    plus three of the prior's standard deviations there (`prior_cov`, 2x2 horizontal): where the last match left a
    direction unknown, no object is judged along it."""
    k = objects[use]
    nx, ny, e = n[use, 0], n[use, 1], r[use]
    steps = np.zeros((count, 2))
    judged = np.flatnonzero(np.bincount(k, minlength=count) >= MIN_CELLS)
    if not len(judged):
        return steps
    A = np.zeros((count, 2, 2))
    A[:, 0, 0] = np.bincount(k, nx * nx, count)
    A[:, 0, 1] = A[:, 1, 0] = np.bincount(k, nx * ny, count)
    A[:, 1, 1] = np.bincount(k, ny * ny, count)
    b = np.column_stack([np.bincount(k, nx * e, count), np.bincount(k, ny * e, count)])[judged]
    values, vectors = np.linalg.eigh(A[judged])
    measured = values >= MIN_INFORMATION
    along = np.einsum("kij,ki->kj", vectors, b) / np.where(measured, values, 1.0)  # the translation along each eigenvector
    doubt = np.sqrt(np.einsum("kij,il,klj->kj", vectors, prior_cov, vectors))
    moving = (measured & (np.abs(along) > min_step_m + 3.0 * doubt)).any(axis=1)
    steps[judged[moving]] = np.einsum("kij,kj->ki", vectors[moving], np.where(measured, along, 0.0)[moving])
    return steps
