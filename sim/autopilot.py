"""Baseline autopilot: line-of-sight path following of the route and a speed controller.

Fed a pose (world<-base_link, 4x4; any estimator's, or the truth) once per control period, it
gives the two thruster commands. Guidance: the desired heading points at a spot `lookahead_m`
ahead on the route (Fossen's lookahead-based LOS, psi_d = path heading - atan(cross_track /
lookahead)) and the desired yaw rate follows the route's curvature at the cruise speed. Heading:
PD on the heading and rate errors plus the differential thrust that holds that rate against the
yaw damping. The yaw rate comes from the boat's gyro when given, else from successive headings.
Speed: the thrust that holds the cruise speed in still water plus PI on the speed over ground,
differenced from positions `speed_window_s` apart. What it is fed is all it knows: a frozen or
jumping position steers the boat as it would steer a real one.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from riverbench.angles import wrap_angle
from sim.dynamics import WamvDynamics
from worlds.route import Route


class AutopilotConfig(BaseModel):
    """Gains and guidance of the baseline controller (commands are thruster fractions in [-1, 1])."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    lookahead_m: float = Field(8.0, gt=0, description="LOS lookahead distance (about 1.6 hull lengths)")
    heading_kp: float = Field(1.0, ge=0, description="differential command per radian of heading error")
    heading_kd: float = Field(1.5, ge=0, description="differential command per rad/s of yaw-rate error")
    rate_filter_s: float = Field(0.3, gt=0, description="low-pass time constant of a yaw rate differenced from headings")
    speed_kp: float = Field(0.2, ge=0, description="common command per m/s of speed error")
    speed_ki: float = Field(0.02, ge=0, description="common command per m of integrated speed error")
    speed_window_s: float = Field(3.0, gt=0, description="baseline of the speed over ground differenced from positions")


class Autopilot:
    """`commands(t, pose, yaw_rate=None)` -> (left, right) thruster commands for the next control period."""

    def __init__(self, route: Route, dynamics: WamvDynamics, speed_mps: float, config: AutopilotConfig | None = None):
        self.route, self.dynamics, self.config, self.speed_mps = route, dynamics, config or AutopilotConfig(), speed_mps
        self.cruise = dynamics.cruise_command(speed_mps)
        self._positions: deque[tuple[float, np.ndarray]] = deque()
        self._heading: tuple[float, float] | None = None
        self._rate = 0.0
        self._speed = speed_mps
        self._integral = 0.0
        self._curvature = np.gradient(route.heading, route.s) if len(route.s) > 1 else np.zeros(1)

    def commands(self, t: float, pose: np.ndarray, yaw_rate: float | None = None) -> tuple[float, float]:
        """Thruster commands from the pose (and gyro rate) believed at time t; an unknown pose holds cruise straight ahead."""
        pose = np.asarray(pose, dtype=float)
        if not np.isfinite(pose).all():
            self._positions.clear()
            self._heading = None
            return self.cruise, self.cruise
        xy, yaw = pose[:2, 3].copy(), math.atan2(pose[1, 0], pose[0, 0])
        rate = self._yaw_rate(t, yaw) if yaw_rate is None or not math.isfinite(yaw_rate) else yaw_rate
        base = self._speed_command(t, xy)
        station, cross, path_heading = self.route.project(xy)
        cfg = self.config
        desired = float(path_heading) - math.atan2(float(cross), cfg.lookahead_m)
        rate_ref = self.speed_mps * float(np.interp(station, self.route.s, self._curvature))
        d = self.dynamics
        hold = (d.n_r * rate_ref + d.n_rr * abs(rate_ref) * rate_ref) / (2.0 * d.thruster_y_m * d.max_thrust_fwd_n)
        turn = cfg.heading_kp * wrap_angle(desired - yaw) + cfg.heading_kd * (rate_ref - rate) + hold
        return float(np.clip(base - turn, -1.0, 1.0)), float(np.clip(base + turn, -1.0, 1.0))

    def _yaw_rate(self, t: float, yaw: float) -> float:
        if self._heading is not None and t > self._heading[0]:
            dt = t - self._heading[0]
            self._rate += (1.0 - math.exp(-dt / self.config.rate_filter_s)) * (wrap_angle(yaw - self._heading[1]) / dt - self._rate)
        self._heading = (t, yaw)
        return self._rate

    def _speed_command(self, t: float, xy: np.ndarray) -> float:
        """Feed-forward cruise thrust plus PI on the speed over ground over the last speed_window_s."""
        cfg = self.config
        self._positions.append((t, xy))
        while len(self._positions) > 2 and self._positions[1][0] <= t - cfg.speed_window_s:
            self._positions.popleft()
        t0, xy0 = self._positions[0]
        if t - t0 >= 0.5 * cfg.speed_window_s:
            self._speed = min(float(np.hypot(*(xy - xy0))) / (t - t0), 2.0 * self.speed_mps + 1.0)
            dt = t - (self._positions[-2][0] if len(self._positions) > 1 else t)
            self._integral = float(np.clip(self._integral + (self.speed_mps - self._speed) * dt, -10.0, 10.0))
        base = self.cruise + cfg.speed_kp * (self.speed_mps - self._speed) + cfg.speed_ki * self._integral
        return float(np.clip(base, -1.0, 1.0))
