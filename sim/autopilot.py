"""Baseline autopilot: line-of-sight path following of the route and a speed controller.

Fed a pose (world<-base_link, 4x4; any estimator's, or the truth) once per control period, it
gives the two thruster commands. Guidance: the desired heading points at a spot `lookahead_m`
ahead on the route (Fossen's lookahead-based LOS, psi_d = path heading - atan(cross_track /
lookahead)). Heading: PD on the heading error, the rate differenced from successive poses.
Speed: the thrust that holds the cruise speed in still water (feed-forward) plus PI on the speed
over ground differenced from successive poses (low-passed). What it is fed is all it knows: a
frozen or jumping pose steers the boat as it would steer a real one.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from sim.dynamics import WamvDynamics
from worlds.route import Route


class AutopilotConfig(BaseModel):
    """Gains and guidance of the baseline controller (commands are thruster fractions in [-1, 1])."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    lookahead_m: float = Field(12.0, gt=0, description="LOS lookahead distance (about 2.5 hull lengths)")
    heading_kp: float = Field(1.2, ge=0, description="differential command per radian of heading error")
    heading_kd: float = Field(2.0, ge=0, description="differential command per rad/s of yaw rate")
    speed_kp: float = Field(0.3, ge=0, description="common command per m/s of speed error")
    speed_ki: float = Field(0.05, ge=0, description="common command per m of integrated speed error")
    speed_filter_s: float = Field(1.0, gt=0, description="time constant of the speed's low-pass filter")
    rate_filter_s: float = Field(0.2, gt=0, description="time constant of the yaw rate's low-pass filter")


class Autopilot:
    """`commands(t, pose)` -> (left, right) thruster commands for the next control period."""

    def __init__(self, route: Route, dynamics: WamvDynamics, speed_mps: float, config: AutopilotConfig | None = None):
        self.route, self.config, self.speed_mps = route, config or AutopilotConfig(), speed_mps
        self.cruise = dynamics.cruise_command(speed_mps)
        self._last: tuple[float, np.ndarray, float] | None = None
        self._speed = speed_mps
        self._rate = 0.0
        self._integral = 0.0

    def commands(self, t: float, pose: np.ndarray) -> tuple[float, float]:
        """Thruster commands from the pose believed at time t; an unknown (non-finite) pose holds cruise straight ahead."""
        cfg = self.config
        pose = np.asarray(pose, dtype=float)
        if not np.isfinite(pose).all():
            self._last = None
            return self.cruise, self.cruise
        xy, yaw = pose[:2, 3], math.atan2(pose[1, 0], pose[0, 0])
        if self._last is not None and t > self._last[0]:
            dt = t - self._last[0]
            speed = min(float(np.hypot(*(xy - self._last[1]))) / dt, 2.0 * self.speed_mps + 1.0)
            self._speed += (1.0 - math.exp(-dt / cfg.speed_filter_s)) * (speed - self._speed)
            self._rate += (1.0 - math.exp(-dt / cfg.rate_filter_s)) * (_wrap(yaw - self._last[2]) / dt - self._rate)
            self._integral = float(np.clip(self._integral + (self.speed_mps - self._speed) * dt, -5.0, 5.0))
        self._last = (t, xy, yaw)
        _, cross, path_heading = self.route.project(xy)
        desired = float(path_heading) - math.atan2(float(cross), cfg.lookahead_m)
        turn = cfg.heading_kp * _wrap(desired - yaw) - cfg.heading_kd * self._rate
        base = self.cruise + cfg.speed_kp * (self.speed_mps - self._speed) + cfg.speed_ki * self._integral
        base = float(np.clip(base, -1.0, 1.0))
        return float(np.clip(base - turn, -1.0, 1.0)), float(np.clip(base + turn, -1.0, 1.0))


def _wrap(angle: float) -> float:
    """Angle in (-pi, pi]."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi
