"""gps_only: the receiver's output as it is, the baseline every report shows.

Position is the latest fix the receiver gave a position in (its own dead reckoning included),
minus the antenna lever arm; heading is the GPS course over ground. During a no-fix stretch the
last output is held. The monitor (default 'none') only labels fixes; it does not change the pose.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from fusion.bootstrap import HEADING_FROM_MOTION, HEADING_UNKNOWN
from fusion.estimator import Estimator
from fusion.geometry import drot2, rot2
from fusion.monitors import Monitor
from fusion.observation import FixObservation
from fusion.params import EstimatorParams
from fusion.verdict import Verdict


class GpsOnlyParams(EstimatorParams):
    """gps_only parameters on top of the shared ones: the receiver's output taken as it is."""

    monitor: str = Field("none", description="GPS integrity monitor; it only labels fixes, the pose is unchanged [none]")
    accept_dead_reckoning: bool = Field(
        True, description="use the receiver's own dead-reckoned output (GGA 6) as a fix [True: the receiver's output as it is]"
    )
    course_min_m: float = Field(10.0, gt=0, description="GPS travel needed to update the course-over-ground heading [10 m]")


class GpsOnly(Estimator):
    """Pose from the latest receiver output; never uses odometry."""

    name = "gps_only"
    uses_odometry = False

    def __init__(self, params: GpsOnlyParams, monitor: Monitor) -> None:
        super().__init__(params, monitor)
        self.params: GpsOnlyParams = params
        self._last: FixObservation | None = None
        self._course_from: np.ndarray | None = None
        self._yaw = 0.0
        self._yaw_var = math.pi**2

    @property
    def initialized(self) -> bool:
        return self._last is not None

    def _try_initialise(self, obs: FixObservation) -> None:
        """Initialised by its first fix, in _use_fix."""

    def _find_heading(self, obs: FixObservation) -> None:
        """Its heading is its own course over the GPS track, in _take."""

    def _use_fix(self, obs: FixObservation, verdict: Verdict) -> None:
        self._take(obs)

    def _take(self, obs: FixObservation) -> None:
        if self._course_from is None:
            self._course_from = obs.xy
        d = obs.xy - self._course_from
        if float(np.hypot(*d)) >= self.params.course_min_m:
            self._yaw = math.atan2(d[1], d[0])
            self._yaw_var = 2.0 * float(np.trace(obs.cov)) / float(d @ d)
            self._course_from = obs.xy
            if math.isnan(self.heading_at):
                self.heading_from, self.heading_at = HEADING_FROM_MOTION, obs.stamp
        if self._last is None and math.isnan(self.position_at):
            self.heading_from, self.position_at = HEADING_UNKNOWN, obs.stamp
        self._last = obs
        self._update_height(obs)

    def _predict(self, stamp: float, yaw_step: float | None = None) -> None:
        """The receiver's last output holds until the next one."""

    def _odometry(self, stamp: float, step: np.ndarray, step_cov: np.ndarray) -> str:
        return ""

    def _restart(self) -> None:
        self._last = None

    def _latest(self) -> FixObservation:
        """The receiver's last output (asked for only once initialised, i.e. once there is one)."""
        assert self._last is not None
        return self._last

    def _pose3(self) -> np.ndarray:
        xy = self._latest().xy - rot2(self._yaw) @ self.lever
        return np.array([xy[0], xy[1], self._yaw])

    def _cov3(self) -> np.ndarray:
        cov = np.zeros((3, 3))
        cov[:2, :2] = self._latest().cov
        cov[2, 2] = self._yaw_var
        return cov

    def _predicted_antenna(self, obs: FixObservation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        j = drot2(self._yaw) @ self.lever
        last = self._latest()
        return last.xy.copy(), last.cov + np.outer(j, j) * self._yaw_var, obs.cov

    def _heading(self) -> tuple[float, float]:
        return self._yaw, self._yaw_var
