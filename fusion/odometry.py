"""OdometryTrack: the scan-matching pose chain in its own frame, queried at fix times with covariance."""

from __future__ import annotations

import bisect

import numpy as np

from fusion.geometry import compose, rot2
from riverbench.angles import wrap_angle


class OdometryTrack:
    """Chain of planar scan-matching steps (nodes at good scans); a break (a restarted matcher)
    starts a new segment. Keeps only the last `horizon_s` seconds, so memory stays flat."""

    def __init__(self, horizon_s: float = 120.0, max_extrapolation_s: float = 1.0) -> None:
        self.horizon_s = horizon_s
        self.max_extrapolation_s = max_extrapolation_s
        self._stamps: list[float] = []
        self._poses: list[np.ndarray] = []  # node pose in the odometry frame
        self._steps: list[np.ndarray] = []  # step from the previous node, in its body frame
        self._covs: list[np.ndarray] = []  # covariance of that step
        self._segments: list[int] = []
        self._segment = 0

    def __len__(self) -> int:
        return len(self._stamps)

    @property
    def segment(self) -> int | None:
        """Segment of the last node (None when empty)."""
        return self._segments[-1] if self._segments else None

    @property
    def last_pose(self) -> np.ndarray | None:
        return self._poses[-1] if self._poses else None

    @property
    def last_stamp(self) -> float | None:
        return self._stamps[-1] if self._stamps else None

    def velocity(self) -> tuple[np.ndarray, np.ndarray] | None:
        """Body-frame (v_forward, v_left, yaw_rate) of the last step and its 3x3 covariance, or None."""
        if len(self._stamps) < 2 or self._segments[-1] != self._segments[-2] or self._stamps[-1] <= self._stamps[-2]:
            return None
        dt = self._stamps[-1] - self._stamps[-2]
        return self._steps[-1] / dt, self._covs[-1] / dt**2

    def anchor(self, stamp: float) -> None:
        """Start a new segment at a reference scan (the matcher's next result is relative to it)."""
        self._segment += 1
        pose = self._poses[-1].copy() if self._poses else np.zeros(3)
        self._push(stamp, pose, np.zeros(3), np.zeros((3, 3)))

    def add(self, stamp: float, step: np.ndarray, step_cov: np.ndarray) -> None:
        """Append a good scan reached by `step` (body frame of the previous node) from the last node."""
        if not self._stamps:
            self.anchor(stamp)
            return
        self._push(stamp, compose(self._poses[-1], step), step.copy(), step_cov.copy())

    def _push(self, stamp: float, pose: np.ndarray, step: np.ndarray, cov: np.ndarray) -> None:
        self._stamps.append(stamp)
        self._poses.append(pose)
        self._steps.append(step)
        self._covs.append(cov)
        self._segments.append(self._segment)
        cut = bisect.bisect_left(self._stamps, stamp - self.horizon_s)
        if cut > 64:  # prune in chunks
            for store in (self._stamps, self._poses, self._steps, self._covs, self._segments):
                del store[:cut]

    def pose_at(self, t: float) -> np.ndarray | None:
        """Pose in the odometry frame at time t (interpolated, or extrapolated a little), or None."""
        located = self._locate(t)
        return None if located is None else located[0]

    def _locate(self, t: float) -> tuple[np.ndarray, int, float] | None:
        """(pose at t, index of the node at or before t, fraction of the next step to add)."""
        i = bisect.bisect_right(self._stamps, t) - 1
        if i < 0:
            return None
        seg, stamps = self._segments, self._stamps
        if i + 1 < len(stamps) and seg[i + 1] == seg[i]:
            frac = (t - stamps[i]) / (stamps[i + 1] - stamps[i]) if stamps[i + 1] > stamps[i] else 0.0
            return compose(self._poses[i], frac * self._steps[i + 1]), i, frac
        if i > 0 and seg[i - 1] == seg[i] and t - stamps[i] <= self.max_extrapolation_s:
            dt = stamps[i] - stamps[i - 1]
            frac = (t - stamps[i]) / dt if dt > 0 else 0.0
            return compose(self._poses[i], frac * self._steps[i]), i, frac
        if t == stamps[i]:
            return self._poses[i].copy(), i, 0.0
        return None

    def displacement(self, t_a: float, t_b: float, lever: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
        """Displacement of a point `lever` (body x, y) from t_a to t_b, in the odometry frame, its 2x2
        covariance, and the odometry-frame yaw at t_b; None when the chain does not cover both times.

        The covariance sums, over the steps spanning [t_a, t_b] (conservatively whole steps), each
        step's covariance mapped to the end pose: translation noise rotated by the heading before
        the step, heading noise swinging the rest of the path about the step's start.
        """
        a, b = self._locate(t_a), self._locate(t_b)
        if a is None or b is None or self._segments[a[1]] != self._segments[b[1]]:
            return None
        pose_a, pose_b = a[0], b[0]
        lo, hi = a[1] + 1, min(b[1] + 1, len(self._stamps) - 1)
        end = pose_b[:2] + rot2(pose_b[2]) @ lever
        cov = np.zeros((2, 2))
        if hi >= lo:
            before = np.array(self._poses[lo - 1 : hi])  # poses before each step
            after = np.array(self._poses[lo : hi + 1])
            covs = np.array(self._covs[lo : hi + 1])
            if b[1] + 1 > len(self._stamps) - 1:  # extrapolating past the last node: part of its step again
                before = np.vstack([before, self._poses[-1]])
                after = np.vstack([after, pose_b])
                covs = np.concatenate([covs, (b[2] ** 2 * self._covs[-1])[None]])
            c, s = np.cos(before[:, 2]), np.sin(before[:, 2])
            arm = end - after[:, :2]
            G = np.zeros((len(before), 2, 3))
            G[:, 0, 0], G[:, 0, 1], G[:, 1, 0], G[:, 1, 1] = c, -s, s, c
            G[:, 0, 2], G[:, 1, 2] = -arm[:, 1], arm[:, 0]
            cov = np.einsum("nij,njk,nlk->il", G, covs, G)
        elif b[2] > 0:  # both times inside the last extrapolated step
            k = len(self._stamps) - 1
            G = np.zeros((2, 3))
            G[:, :2] = rot2(self._poses[k][2])
            arm = end - pose_b[:2]
            G[:, 2] = (-arm[1], arm[0])
            cov = b[2] ** 2 * G @ self._covs[k] @ G.T
        start = pose_a[:2] + rot2(pose_a[2]) @ lever
        return end - start, cov, float(wrap_angle(pose_b[2]))
