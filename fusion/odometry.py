"""OdometryTrack: the scan-matching pose chain in its own frame, queried at fix times with covariance."""

from __future__ import annotations

import bisect
from dataclasses import dataclass

import numpy as np

from fusion.geometry import between, compose, compose_jacobians, drot2, rot2, wrap


@dataclass(frozen=True)
class Node:
    """A good scan: its stamp, its pose in the odometry frame, the step and covariance from the node before."""

    stamp: float
    pose: np.ndarray
    step: np.ndarray
    step_cov: np.ndarray
    segment: int


class OdometryTrack:
    """Chain of planar scan-matching steps; a break (rejected match) starts a new segment.

    Keeps only the last `horizon_s` seconds, so memory stays flat in the run length.
    """

    def __init__(self, horizon_s: float = 120.0, max_extrapolation_s: float = 1.0) -> None:
        self.horizon_s = horizon_s
        self.max_extrapolation_s = max_extrapolation_s
        self._nodes: list[Node] = []
        self._segment = 0

    @property
    def last(self) -> Node | None:
        return self._nodes[-1] if self._nodes else None

    def velocity(self) -> np.ndarray | None:
        """Body-frame (v_forward, v_left, yaw_rate) of the last step, or None without one."""
        if len(self._nodes) < 2:
            return None
        last, prev = self._nodes[-1], self._nodes[-2]
        if last.segment != prev.segment or last.stamp <= prev.stamp:
            return None
        return last.step / (last.stamp - prev.stamp)

    def anchor(self, stamp: float) -> None:
        """Start a new segment at a reference scan (the matcher's next result is relative to it)."""
        pose = self._nodes[-1].pose if self._nodes else np.zeros(3)
        self._segment += 1
        self._push(Node(stamp, pose.copy(), np.zeros(3), np.zeros((3, 3)), self._segment))

    def add(self, stamp: float, step: np.ndarray, step_cov: np.ndarray) -> None:
        """Append a good scan reached by `step` (body frame of the previous node) from the last node."""
        if not self._nodes:
            self.anchor(stamp)
            return
        prev = self._nodes[-1]
        self._push(Node(stamp, compose(prev.pose, step), step.copy(), step_cov.copy(), prev.segment))

    def _push(self, node: Node) -> None:
        self._nodes.append(node)
        cut = bisect.bisect_left([n.stamp for n in self._nodes[:64]], node.stamp - self.horizon_s)
        if cut:
            del self._nodes[:cut]

    def _index_at_or_before(self, t: float) -> int:
        return bisect.bisect_right([n.stamp for n in self._nodes], t) - 1

    def pose_at(self, t: float) -> np.ndarray | None:
        """Pose in the odometry frame at time t (interpolated, or extrapolated a little), or None."""
        located = self._locate(t)
        return None if located is None else located[0]

    def _locate(self, t: float) -> tuple[np.ndarray, int, float] | None:
        """(pose at t, index of the node at or before t, fraction of the next step to add)."""
        i = self._index_at_or_before(t)
        if i < 0:
            return None
        node = self._nodes[i]
        if i + 1 < len(self._nodes) and self._nodes[i + 1].segment == node.segment:
            nxt = self._nodes[i + 1]
            frac = (t - node.stamp) / (nxt.stamp - node.stamp) if nxt.stamp > node.stamp else 0.0
            return compose(node.pose, frac * nxt.step), i, frac
        if i > 0 and self._nodes[i - 1].segment == node.segment and t - node.stamp <= self.max_extrapolation_s:
            dt = node.stamp - self._nodes[i - 1].stamp
            frac = (t - node.stamp) / dt if dt > 0 else 0.0
            return compose(node.pose, frac * node.step), i, frac
        if t == node.stamp:
            return node.pose.copy(), i, 0.0
        return None

    def displacement(self, t_a: float, t_b: float, lever: np.ndarray) -> tuple[np.ndarray, np.ndarray, float] | None:
        """Displacement of a point `lever` (body x, y) from t_a to t_b, in the odometry frame, its 2x2
        covariance, and the odometry-frame yaw at t_b; None when the chain does not cover both times."""
        a, b = self._locate(t_a), self._locate(t_b)
        if a is None or b is None or self._nodes[a[1]].segment != self._nodes[b[1]].segment:
            return None
        pose_a, pose_b = a[0], b[0]
        # Covariance of the relative pose, accumulated in node a's frame over the steps spanning [t_a, t_b].
        rel = np.zeros(3)
        cov = np.zeros((3, 3))
        for k in range(a[1] + 1, b[1] + 2):
            if k >= len(self._nodes):
                # extrapolation past the last node: the last step's uncertainty, scaled by the fraction used
                node = self._nodes[-1]
                step, step_cov = b[2] * node.step, max(b[2], 0.0) ** 2 * node.step_cov
            elif k == b[1] + 1:
                step, step_cov = b[2] * self._nodes[k].step, self._nodes[k].step_cov * min(1.0, b[2] + 1e-9)
            else:
                step, step_cov = self._nodes[k].step, self._nodes[k].step_cov
            j_pose, j_step = compose_jacobians(rel, step)
            cov = j_pose @ cov @ j_pose.T + j_step @ step_cov @ j_step.T
            rel = compose(rel, step)
        rel_ab = between(pose_a, pose_b)
        jac = np.zeros((2, 3))
        jac[:, :2] = np.eye(2)
        jac[:, 2] = drot2(rel_ab[2]) @ lever
        d_local = rel_ab[:2] + rot2(rel_ab[2]) @ lever - lever
        r_a = rot2(pose_a[2])
        cov_xy = r_a @ jac @ cov @ jac.T @ r_a.T
        return r_a @ d_local, cov_xy, float(wrap(pose_b[2]))
