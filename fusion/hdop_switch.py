"""hdop_switch: the field study's scheme. Use GPS when the monitor (default 'hdop': quality and HDOP
under a threshold) trusts it, otherwise dead-reckon with the matcher's odometry from the last
trusted fix. The heading is the odometry's, aligned to GPS course whenever trusted fixes span
`realign_baseline_m` along an unbroken odometry chain."""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from fusion.bootstrap import Alignment
from fusion.estimator import Estimator
from fusion.geometry import between, compose, drot2, rot2
from fusion.monitors import Monitor
from fusion.observation import FixObservation
from fusion.params import EstimatorParams
from riverbench.angles import wrap_angle


class HdopSwitchParams(EstimatorParams):
    """hdop_switch parameters on top of the shared ones: the last trusted fix carried forward by odometry."""

    monitor: str = Field("hdop", description="GPS integrity monitor deciding which fixes are trusted [hdop]")
    realign_baseline_m: float = Field(20.0, gt=0, description="trusted GPS travel that re-aligns the odometry heading [20 m]")


class HdopSwitch(Estimator):
    """Last trusted fix, carried forward by odometry; covariance grows with the odometry's."""

    name = "hdop_switch"

    def __init__(self, params: HdopSwitchParams, monitor: Monitor) -> None:
        super().__init__(params, monitor)
        self.params: HdopSwitchParams = params
        self._init = False
        self._offset = 0.0  # world yaw - odometry yaw
        self._offset_var = math.pi**2
        self._anchor_world = np.zeros(3)  # world pose at the anchor
        self._anchor_odo: np.ndarray | None = None  # odometry pose at the anchor
        self._anchor_stamp = 0.0
        self._anchor_cov = np.eye(3)
        self._segment: int | None = None
        self._course: tuple[FixObservation, np.ndarray, int | None] | None = None  # fix, odometry pose, segment

    @property
    def initialized(self) -> bool:
        return self._init

    def _initialise(self, alignment: Alignment) -> None:
        odo = self.odometry.pose_at(alignment.stamp)
        if odo is not None:
            self._offset = float(wrap_angle(alignment.pose[2] - odo[2]))
            self._offset_var = alignment.cov[2, 2]
        self._anchor(alignment.stamp, alignment.pose, alignment.cov)
        self._init = True

    def _anchor(self, stamp: float, world: np.ndarray, cov: np.ndarray) -> None:
        self._anchor_world = world.copy()
        self._anchor_odo = self.odometry.pose_at(stamp)
        self._anchor_stamp = stamp
        self._anchor_cov = cov.copy()
        self._segment = self.odometry.segment

    def _dead_reckoned(self) -> tuple[np.ndarray, np.ndarray]:
        """World pose now and its covariance, carried from the anchor by the odometry."""
        if self._anchor_odo is None or self.odometry.segment is None or self.odometry.segment != self._segment:
            return self._anchor_world.copy(), self._anchor_cov.copy()
        now = self.odometry.pose_at(self.stamp)
        if now is None:
            now = self.odometry.last_pose
        assert now is not None  # the track has a segment, so it has nodes
        pose = compose(self._anchor_world, between(self._anchor_odo, now))
        moved = self.odometry.displacement(self._anchor_stamp, self.stamp, np.zeros(2))
        cov = self._anchor_cov.copy()
        if moved is not None:
            rot = rot2(self._offset)
            cov[:2, :2] += rot @ moved[1] @ rot.T
        return pose, cov

    def _predict(self, stamp: float, yaw_step: float | None = None) -> None:
        """Dead reckoning is evaluated lazily from the odometry track."""

    def _odometry(self, stamp: float, step: np.ndarray, step_cov: np.ndarray) -> str:
        return ""

    def _reanchor(self, stamp: float) -> None:
        """The odometry chain broke at this scan: continue from the new segment where the old one ended."""
        if not self._init or self.odometry.segment is None:
            return
        pose, cov, end = self._anchor_world, self._anchor_cov, self.odometry.last_pose
        assert end is not None  # the track has a segment, so it has nodes
        if self._anchor_odo is not None and self._segment == self.odometry.segment - 1:
            pose = compose(self._anchor_world, between(self._anchor_odo, end))
            cov = cov + np.diag(np.diag(self._default_odom_cov)[[0, 1, 5]])
        self._anchor_world, self._anchor_cov = pose, cov
        self._anchor_odo, self._anchor_stamp, self._segment = end.copy(), stamp, self.odometry.segment

    def _update_fix(self, obs: FixObservation) -> None:
        odo = self.odometry.pose_at(obs.stamp)
        segment = self.odometry.segment
        if odo is not None:
            if self._course is None or self._course[2] != segment:
                self._course = (obs, odo, segment)
            elif float(np.linalg.norm(obs.xy - self._course[0].xy)) >= self.params.realign_baseline_m:
                d_gps = obs.xy - self._course[0].xy
                d_odo = odo[:2] - self._course[1][:2]
                if float(np.linalg.norm(d_odo)) > 0.5 * self.params.realign_baseline_m:
                    self._offset = float(wrap_angle(math.atan2(d_gps[1], d_gps[0]) - math.atan2(d_odo[1], d_odo[0])))
                    self._offset_var = 2.0 * float(np.trace(obs.cov)) / float(d_gps @ d_gps)
                self._course = (obs, odo, segment)
            yaw = float(wrap_angle(odo[2] + self._offset))
        else:
            yaw = float(self._dead_reckoned()[0][2])
        xy = obs.xy - rot2(yaw) @ self.lever
        cov = np.zeros((3, 3))
        cov[:2, :2] = obs.cov
        cov[2, 2] = self._offset_var
        self._anchor(obs.stamp, np.array([xy[0], xy[1], yaw]), cov)

    def _use_fix(self, obs, verdict) -> None:
        if not verdict.trusted:
            self._course = None  # an untrusted fix interrupts the course baseline
        super()._use_fix(obs, verdict)

    def _restart(self) -> None:
        self._init = False

    def _pose3(self) -> np.ndarray:
        return self._dead_reckoned()[0]

    def _cov3(self) -> np.ndarray:
        return self._dead_reckoned()[1]

    def _predicted_antenna(self, obs: FixObservation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        pose, cov = self._dead_reckoned()
        j = drot2(pose[2]) @ self.lever
        return pose[:2] + rot2(pose[2]) @ self.lever, cov[:2, :2] + np.outer(j, j) * cov[2, 2], obs.cov

    def _heading(self) -> tuple[float, float]:
        pose, cov = self._dead_reckoned()
        return float(pose[2]), float(cov[2, 2])
