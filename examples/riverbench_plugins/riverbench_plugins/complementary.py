"""ComplementaryFilter: scan-matching odometry between fixes, pulled towards trusted GPS (a riverbench estimator plugin).

The protocol: a class with a `Params` model subclassing `fusion.BaseEstimatorParams` (so it is given
the matcher, monitor, lidar mount and antenna offset), built as `ComplementaryFilter(params,
monitor)`, fed in time order with `add_fix(fix) -> Verdict` and `add_match(stamp, result)`, and
read through the properties `pose` (4x4 world<-base_link, NaN before initialisation) and `cov`
(3x3 of x, y, yaw; infinite before).
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from fusion import BaseEstimatorParams, Verdict
from fusion.geometry import lidar_to_base, planar, pose_matrix, rot2
from fusion.monitors import FixContext, Monitor
from fusion.observation import FixObservation, screen
from fusion.odometry import OdometryTrack
from matcher import MatchResult
from riverbench.angles import wrap_angle
from sim.gnss_fix import GnssFix


class ComplementaryParams(BaseEstimatorParams):
    """ComplementaryFilter's parameters besides what every estimator is given (defaults in brackets)."""

    monitor: str = "riverbench_plugins.jump:JumpMonitor"
    position_gain: float = Field(0.1, gt=0.0, le=1.0, description="share of a trusted fix's disagreement taken per fix [0.1]")
    heading_gain: float = Field(0.1, gt=0.0, le=1.0, description="share of the GPS course's disagreement taken per course update [0.1]")
    course_min_m: float = Field(10.0, gt=0.0, description="GPS travel between course updates; the first sets the heading [10 m]")
    max_course_error_deg: float = Field(
        10.0, gt=0.0, description="a course update that disagrees more is ignored: a fault the monitor missed [10 deg]"
    )
    uere_m: float = Field(3.0, gt=0.0, description="a fix's per-axis sigma is uere_m * HDOP / sqrt(2) [3 m]")
    match_sigma_m: float = Field(0.2, gt=0.0, description="per-scan sigma assumed for a match without a covariance [0.2 m]")


class ComplementaryFilter:
    """Dead-reckons base_link on the matcher's steps; each trusted fix pulls the position by
    position_gain, each GPS course over course_min_m the heading by heading_gain."""

    name = "complementary"
    Params = ComplementaryParams

    def __init__(self, params: ComplementaryParams, monitor: Monitor) -> None:
        self.params = params
        self.monitor = monitor
        self._mount = np.asarray(params.mount, dtype=float)
        self._lever = np.asarray(params.antenna[:2], dtype=float)
        self._track = OdometryTrack()
        self._xy: np.ndarray | None = None
        self._var = math.inf  # per-axis position variance
        self._yaw: float | None = None
        self._yaw_var = math.inf
        self._course_from: FixObservation | None = None

    @property
    def pose(self) -> np.ndarray:
        """4x4 world<-base_link now (NaN until a position and a heading are known)."""
        if self._xy is None or self._yaw is None:
            return np.full((4, 4), np.nan)
        return pose_matrix(self._xy[0], self._xy[1], 0.0, self._yaw)

    @property
    def cov(self) -> np.ndarray:
        """3x3 covariance of (x, y, yaw) (infinite until initialised)."""
        if self._xy is None or self._yaw is None:
            return np.full((3, 3), np.inf)
        return np.diag([self._var, self._var, self._yaw_var])

    def add_match(self, stamp: float, result: MatchResult) -> None:
        """Dead-reckon on a good match; a failed one (not gated) restarts the odometry chain at this scan."""
        if not result.ok:
            if not result.info.get("gated", False):
                self._track.anchor(stamp)
            return
        sigma = self.params.match_sigma_m
        cov6 = np.diag([sigma**2] * 3 + [(sigma / 10.0) ** 2] * 3) if result.cov is None else np.asarray(result.cov, dtype=float)
        step, step_cov = planar(*lidar_to_base(np.asarray(result.T, dtype=float), cov6, self._mount))
        self._track.add(stamp, step, step_cov)
        if self._xy is not None and self._yaw is not None:
            self._xy = self._xy + rot2(self._yaw) @ step[:2]
            self._yaw = float(wrap_angle(self._yaw + step[2]))
            self._var += float(np.trace(step_cov[:2, :2])) / 2.0
            self._yaw_var += float(step_cov[2, 2])

    def add_fix(self, fix: GnssFix) -> Verdict:
        """Judge the fix with the monitor and take a trusted one; return the verdict."""
        obs, why = screen(fix, self.params.uere_m, accept_dead_reckoning=False)
        if obs is None:
            self.monitor.note_outage(float(fix.stamp))
            return Verdict(False, math.inf if "dead reckoning" in why else math.nan, why)
        verdict = self.monitor.check(obs, self._context(obs))
        self.monitor.commit(obs, verdict)
        if verdict.trusted:
            self._take(obs)
        return verdict

    def _context(self, obs: FixObservation) -> FixContext:
        """What the monitor may compare the fix with: the predicted antenna position, the heading, the odometry."""
        known = self._xy is not None and self._yaw is not None
        predicted = (self._antenna(), np.eye(2) * self._var, obs.cov) if known else None
        return FixContext(predicted=predicted, yaw=self._yaw, yaw_var=self._yaw_var if known else None, lever=self._lever, odometry=self._track)

    def _antenna(self) -> np.ndarray:
        """The antenna's (x, y) by the current estimate."""
        return self._xy + rot2(self._yaw or 0.0) @ self._lever

    def _take(self, obs: FixObservation) -> None:
        """Pull the position towards a trusted fix (set it, before a heading is known) and update the heading."""
        fix_var = float(obs.cov[0, 0])
        if self._xy is None or self._yaw is None:
            self._xy, self._var = obs.xy - rot2(self._yaw or 0.0) @ self._lever, fix_var
        else:
            k = self.params.position_gain
            self._xy = self._xy + k * (obs.xy - self._antenna())
            self._var = (1.0 - k) ** 2 * self._var + k**2 * fix_var
        self._update_heading(obs)

    def _update_heading(self, obs: FixObservation) -> None:
        """Compare the GPS course since the last course update with the odometry's (or, without odometry, with the heading)."""
        start = self._course_from
        if start is None:
            self._course_from = obs
            return
        d_gps = obs.xy - start.xy
        if float(np.hypot(*d_gps)) < self.params.course_min_m:
            return
        self._course_from = obs
        course = math.atan2(d_gps[1], d_gps[0])
        course_var = 2.0 * float(obs.cov[0, 0]) / float(d_gps @ d_gps)
        moved = self._track.displacement(start.stamp, obs.stamp, self._lever)
        if moved is not None and float(np.hypot(*moved[0])) > 0.5 * self.params.course_min_m:
            d_odo, _, odo_yaw = moved
            implied = course - math.atan2(d_odo[1], d_odo[0]) + odo_yaw  # the heading now that makes both courses agree
        elif self._yaw is None:
            implied = course  # no usable odometry: the boat heads where it goes
        else:
            return
        if self._yaw is None:
            self._yaw, self._yaw_var = float(wrap_angle(implied)), course_var
            self._xy = obs.xy - rot2(self._yaw) @ self._lever
            return
        error = float(wrap_angle(implied - self._yaw))
        if abs(error) > math.radians(self.params.max_course_error_deg):
            return
        k = self.params.heading_gain
        self._yaw = float(wrap_angle(self._yaw + k * error))
        self._yaw_var = (1.0 - k) ** 2 * self._yaw_var + k**2 * course_var
