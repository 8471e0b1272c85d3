"""An outside trajectory laid onto a run's scans as the bench lays its own components: moved to base_link, each scan
given the pose stamped nearest it (within a quarter of a revolution: a scan without one is a dropped frame), and
anchored in the world as its contract declares (scenarios.score.external.Contract.anchor).

- map: the poses are in the run's map frame already (an estimator's output), used as they are.
- first: odometry from its first pose (identity for KISS-ICP and most LiDAR odometry), composed onto the truth at the
  scan of that pose, as the bench chains a matcher's odometry from the true start pose.
- se2, se3: odometry in a frame of its own, moved by the rigid motion that best fits its positions to the truth's
  (scenarios.score.metrics.align_se2, align_se3: planar, or 3-D as evo's -a).
"""

from __future__ import annotations

import numpy as np

from scenarios.score.metrics import align_se2, align_se3

SCAN_TOLERANCE = 0.25
"""How far from a scan's stamp (in revolutions) a pose may be stamped and still be that scan's."""


def to_base_link(poses: np.ndarray, frame: str, mount: np.ndarray) -> np.ndarray:
    """World<-base_link poses from poses of `frame` (base_link, or lidar: world<-lidar times lidar<-base_link)."""
    return poses @ np.linalg.inv(mount) if frame == "lidar" else poses


def nearest(t: np.ndarray, query: np.ndarray, tolerance_s: float) -> tuple[np.ndarray, np.ndarray]:
    """For each query time, the index of the sorted stamp `t` nearest it and whether that stamp is within `tolerance_s`
    (t must not be empty)."""
    right = np.clip(np.searchsorted(t, query), 0, len(t) - 1)
    left = np.clip(right - 1, 0, len(t) - 1)
    index = np.where(np.abs(t[left] - query) <= np.abs(t[right] - query), left, right)
    return index, np.abs(t[index] - query) <= tolerance_s


def on_scans(t: np.ndarray, poses: np.ndarray, scan_t: np.ndarray, tolerance_s: float) -> np.ndarray:
    """(len(scan_t), 4, 4): each scan's pose, the one stamped nearest it within `tolerance_s`, NaN where there is none."""
    out = np.full((len(scan_t), 4, 4), np.nan)
    if not len(t):
        return out
    index, hit = nearest(t, scan_t, tolerance_s)
    out[hit] = poses[index[hit]]
    return out


def anchored(poses: np.ndarray, truth: np.ndarray, anchor: str) -> np.ndarray:
    """The poses at the scans (NaN: none) laid onto the world as `anchor` says, against the truth at the same scans."""
    if anchor == "map":
        return poses
    if anchor == "se2":
        return align_se2(poses, truth)
    if anchor == "se3":
        return align_se3(poses, truth)
    have = np.isfinite(poses).all(axis=(1, 2))
    if not have.any():
        return poses
    k = int(np.argmax(have))
    return truth[k] @ np.linalg.inv(poses[k]) @ poses
