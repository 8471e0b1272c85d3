"""Monitor 'consistency': GPS displacement against scan-matching displacement, with a re-acquisition guard.

Two tests, each a 2-dof Mahalanobis distance of (GPS displacement - odometry displacement) with
both covariances (GPS from HDOP, odometry from the matcher's covariances chained, rotated into the
world by the filter's heading with its variance):
- window: against the fix about `window_s` earlier; differencing cancels a slowly varying bias and
  catches a multipath jump at its onset.
- chain: against the last trusted fix (up to `reference_max_age_s` old), so that a bias that
  persists after its onset stays flagged.
Guard: after a stretch of at least `gap_s` without a measured fix (a blackout, or start-up), the
receiver's own filter may carry a wrong estimate that it smooths back slowly; fixes stay
untrusted for at least `guard_s` and until `guard_n` consecutive window tests pass the tighter
`guard_gate_prob` gate (the receiver's track moves with the odometry again).
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.stats import chi2

from fusion.geometry import drot2, rot2
from fusion.monitors.base import FixContext, Monitor
from fusion.observation import FixObservation
from fusion.verdict import Verdict


class ConsistencyParams(BaseModel):
    """Defaults: window 2 s, gate 0.999 (13.8), chain reference up to 60 s old, guard after a 2 s gap
    for at least 5 s and 5 consecutive window tests under the 0.99 gate (9.2)."""

    model_config = ConfigDict(extra="forbid")
    window_s: float = Field(2.0, gt=0)
    gate_prob: float = Field(0.999, gt=0.5, lt=1.0)
    reference_max_age_s: float = Field(60.0, gt=0)
    gap_s: float = Field(2.0, gt=0)
    guard_s: float = Field(5.0, ge=0)
    guard_n: int = Field(5, ge=0)
    guard_gate_prob: float = Field(0.99, gt=0.5, lt=1.0)


class ConsistencyMonitor(Monitor):
    """GPS-vs-odometry displacement tests plus the re-acquisition guard; statistic is the larger distance."""

    name = "consistency"

    def __init__(self, params: ConsistencyParams) -> None:
        self.params = params
        self.gate = float(chi2.ppf(params.gate_prob, 2))
        self.guard_gate = float(chi2.ppf(params.guard_gate_prob, 2))
        self._history: deque[FixObservation] = deque()
        self._last_trusted: FixObservation | None = None
        self._last_measured: float | None = None
        self._guard_start: float | None = None
        self._guard_passes = 0
        self._pending_window_d2 = math.nan

    def _distance(self, ref: FixObservation, obs: FixObservation, ctx: FixContext) -> float:
        """Mahalanobis distance squared of the GPS displacement from ref to obs against the odometry's."""
        moved = ctx.odometry.displacement(ref.stamp, obs.stamp, ctx.lever)
        if moved is None or ctx.yaw is None:
            return math.nan
        d_odo, cov_odo, odo_yaw = moved
        offset = ctx.yaw - odo_yaw
        rot = rot2(offset)
        d_world = rot @ d_odo
        j_yaw = drot2(offset) @ d_odo
        cov = rot @ cov_odo @ rot.T + np.outer(j_yaw, j_yaw) * (ctx.yaw_var or 0.0) + ref.cov + obs.cov
        r = (obs.xy - ref.xy) - d_world
        return float(r @ np.linalg.solve(cov, r))

    def _window_reference(self, stamp: float) -> FixObservation | None:
        target = stamp - self.params.window_s
        best = None
        for old in self._history:
            if old.stamp <= stamp - 0.5 * self.params.window_s and old.stamp >= stamp - 2.0 * self.params.window_s:
                if best is None or abs(old.stamp - target) < abs(best.stamp - target):
                    best = old
        return best

    def _in_guard(self, stamp: float) -> bool:
        if self._guard_start is None:
            return False
        return stamp - self._guard_start < self.params.guard_s or self._guard_passes < self.params.guard_n

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        if self._last_measured is None or obs.stamp - self._last_measured >= self.params.gap_s:
            guard_start = obs.stamp
        else:
            guard_start = self._guard_start
        window_ref = self._window_reference(obs.stamp)
        window_d2 = math.nan if window_ref is None else self._distance(window_ref, obs, ctx)
        chain_d2 = math.nan
        ref = self._last_trusted
        if ref is not None and obs.stamp - ref.stamp <= self.params.reference_max_age_s:
            chain_d2 = self._distance(ref, obs, ctx)
        self._pending_window_d2 = window_d2
        tests = [d for d in (window_d2, chain_d2) if not math.isnan(d)]
        statistic = max(tests) if tests else math.nan
        passes = self._guard_passes if guard_start == self._guard_start else 0
        in_guard = guard_start is not None and (
            obs.stamp - guard_start < self.params.guard_s or passes < self.params.guard_n
        )
        if tests and statistic > self.gate:
            which = "window" if window_d2 == statistic else "chain"
            return Verdict(False, statistic, f"{which} displacement test {statistic:.1f} > gate {self.gate:.1f}")
        if in_guard:
            return Verdict(False, statistic, f"re-acquisition guard ({passes}/{self.params.guard_n} consistent)")
        if not tests:
            return Verdict(True, statistic, "unchecked: no odometry or reference to compare")
        return Verdict(True, statistic, "displacement consistent")

    def commit(self, obs: FixObservation, verdict: Verdict) -> None:
        if self._last_measured is None or obs.stamp - self._last_measured >= self.params.gap_s:
            self._guard_start = obs.stamp
            self._guard_passes = 0
            self._history.clear()
        if self._guard_start is not None:
            # without odometry to compare (nan) the guard can only wait out guard_s
            if math.isnan(self._pending_window_d2) or self._pending_window_d2 <= self.guard_gate:
                self._guard_passes += 1
            else:
                self._guard_passes = 0
            if not self._in_guard(obs.stamp):
                self._guard_start = None
        self._last_measured = obs.stamp
        self._history.append(obs)
        while self._history and self._history[0].stamp < obs.stamp - 2.0 * self.params.window_s:
            self._history.popleft()
        if verdict.trusted:
            self._last_trusted = obs
