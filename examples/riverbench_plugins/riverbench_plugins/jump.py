"""JumpMonitor: refuses a fix that moved away from a reference track faster than that track follows (a riverbench monitor plugin).

The reference is the antenna position the odometry carries from fix to fix; a trusted fix pulls it
by `follow_gain`, so it follows the receiver's slowly varying error but not a jump, nor the few
seconds in which a receiver's own filter walks onto a wrong position. Without odometry it is the
latest trusted fix, with a gate that grows at `max_speed_mps`.

The protocol: a class with a pydantic `Params` model, built as `JumpMonitor(params)`, with
`check(obs, ctx) -> Verdict` (judges, changes nothing the next check sees), `commit(obs, verdict)`
(the decision the estimator acted on), `reset()` and `note_outage(stamp)`; subclassing
`fusion.monitors.Monitor` gives the last three as no-ops.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from fusion import Verdict
from fusion.geometry import rot2
from fusion.monitors import FixContext, Monitor
from fusion.observation import FixObservation


class JumpParams(BaseModel):
    """JumpMonitor's parameters (defaults in brackets)."""

    model_config = ConfigDict(extra="forbid")
    gate_m: float = Field(4.0, gt=0.0, description="a fix farther than this from the reference is refused [4 m]")
    follow_gain: float = Field(0.05, gt=0.0, le=1.0, description="share of a trusted fix's offset the carried reference takes [0.05]")
    drift_per_m: float = Field(0.02, ge=0.0, description="gate growth per metre carried since the last trusted fix (odometry drift) [0.02]")
    max_speed_mps: float = Field(5.0, gt=0.0, description="without odometry the gate grows at this speed from the reference's time [5 m/s]")
    max_age_s: float = Field(30.0, gt=0.0, description="after this long without a trusted fix the next fix restarts the reference [30 s]")


class JumpMonitor(Monitor):
    """Statistic: the fix's distance (m) from the reference carried to its time."""

    name = "jump"
    Params = JumpParams

    def __init__(self, params: JumpParams) -> None:
        self.params = params
        self.gate = params.gate_m
        self.reset()

    def reset(self) -> None:
        """Forget the reference."""
        self._ref: tuple[float, np.ndarray] | None = None  # stamp and antenna (x, y)
        self._trusted_at = -math.inf
        self._carried_m = 0.0  # odometry travel since the last trusted fix
        self._pending: tuple[np.ndarray, float, bool] | None = None  # what commit needs: the carried reference, travel, by odometry

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        """Trusted unless the fix lies beyond the gate from the reference carried to its time."""
        p = self.params
        self._pending = None
        if self._ref is None or obs.stamp - self._trusted_at > p.max_age_s:
            return Verdict(True, math.nan, "no recent reference: the fix restarts it")
        stamp, xy = self._ref
        moved = ctx.odometry.displacement(stamp, obs.stamp, ctx.lever) if ctx.yaw is not None else None
        if moved is None:
            expected, travel, gate = xy, self._carried_m, p.gate_m + p.max_speed_mps * (obs.stamp - stamp)
        else:
            d_odo, _, odo_yaw = moved
            expected, travel = xy + rot2(ctx.yaw - odo_yaw) @ d_odo, self._carried_m + float(np.hypot(*d_odo))
            gate = p.gate_m + p.drift_per_m * travel
        self._pending = (expected, travel, moved is not None)
        distance = float(np.hypot(*(obs.xy - expected)))
        if distance > gate:
            return Verdict(False, distance, f"{distance:.1f} m from the reference (gate {gate:.1f} m)")
        return Verdict(True, distance, "follows the reference")

    def commit(self, obs: FixObservation, verdict: Verdict) -> None:
        """Carry the reference to this fix; a trusted fix pulls it (takes it, without odometry)."""
        if self._pending is None:
            if verdict.trusted:
                self._ref, self._trusted_at, self._carried_m = (obs.stamp, obs.xy.copy()), obs.stamp, 0.0
            return
        expected, travel, by_odometry = self._pending
        if verdict.trusted:
            gain = self.params.follow_gain if by_odometry else 1.0
            self._ref, self._trusted_at, self._carried_m = (obs.stamp, expected + gain * (obs.xy - expected)), obs.stamp, 0.0
        elif by_odometry:
            self._ref, self._carried_m = (obs.stamp, expected), travel
