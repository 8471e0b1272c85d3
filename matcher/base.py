"""Matcher: the stateful scan-to-previous-good-scan interface shared by every method."""

from __future__ import annotations

import time
from abc import ABC, abstractmethod
from typing import Generic

import numpy as np
from pydantic import Field

from matcher.cloud import Cloud
from matcher.deskew import P
from matcher.gate import GateParams, ScanGate
from matcher.motion import ConstantVelocity, pose_to_xyzrpy
from matcher.result import MatchResult
from sim.scan import Scan

MAX_TILT_DEG = 30.0
"""A vessel floats upright: its roll and pitch oscillate about level with the waves (the library's sea states, up to 4,
tilt a small catamaran by a few degrees; one heeled past 30 deg is capsizing). Odometry whose chained attitude tilts
farther than this from the first scan's has turned the boat over: the match that would take it there is a failed one.
gicp's chain in canal_lock's canyon pitched 1.4 deg a scan, each step a plausible rate, and passed 90 deg in 7 s, which
the Euler yaw reads as a 180 deg turn."""


class MatcherParams(GateParams):
    """Settings common to all matchers (gate, range band, plausibility bounds)."""

    min_range_m: float = Field(1.0, ge=0.0, description="ignore returns closer than this (the vessel itself; default 1 m)")
    max_range_m: float = Field(100.0, gt=0.0, description="ignore returns farther than this (HDL-32E datasheet: 100 m)")
    max_speed_mps: float = Field(
        20.0,
        gt=0.0,
        description="faster estimated motion is a failed match (default 20 m/s: a real recording passes, a boat at 6 kn (3.1 m/s) "
        "or a car at 30 kn (15.4 m/s); the library's vessels do 2-3 m/s)",
    )
    max_yaw_rate_dps: float = Field(60.0, gt=0.0, description="faster estimated turning is a failed match (default 60 deg/s)")
    prior_max_age_s: float = Field(
        1.0, gt=0.0, description="the constant-velocity prior (de-skew, initial guess) is dropped when its last good match is older (default 1 s)"
    )


class Matcher(ABC):
    """Registers each scan against the previous good scan (the reference).

    Template: `register` sanitises the scan, applies the gate, handles the first scan, calls the
    method's `_match`, checks plausibility and keeps the constant-velocity motion prior. A scan
    that passes the gate becomes the new reference even when its match fails (tracking restarts
    from it; the motion prior, the vessel's velocity, is kept until it is `prior_max_age_s` old);
    a gated scan (info['gated']: too few points, a point-count jump, a stamp that does not
    advance) never does."""

    name: str = ""

    def __init__(self, params: MatcherParams) -> None:
        self.params = params
        self.gate = ScanGate(params)
        self.velocity = ConstantVelocity()
        self._ref_stamp: float | None = None
        self._velocity_stamp: float | None = None
        self._attitude = np.eye(3)  # the reference's lidar frame in the first reference's, chained from the good matches

    def register(self, scan: Scan) -> MatchResult:
        """Relative motion of `scan` against the previous good scan; never raises."""
        start = time.perf_counter()
        try:
            result = self._register(scan)
        except Exception as exc:  # a matcher must survive any scan: record the failure instead
            self._forget_reference()
            result = MatchResult.failure(f"matcher error: {type(exc).__name__}: {exc}")
        result.seconds = time.perf_counter() - start
        return result

    def _register(self, scan: Scan) -> MatchResult:
        p = self.params
        cloud = Cloud.from_scan(scan, p.min_range_m, p.max_range_m)
        n = len(cloud)
        verdict = self.gate.check(n)
        if not verdict.ok:
            return MatchResult.failure(verdict.reason, n_points=n, gated=True)
        if self._ref_stamp is None:
            self._set_reference(cloud)
            return MatchResult.failure("first scan", n_points=n)
        dt = cloud.stamp - self._ref_stamp
        if not dt > 0.0:
            return MatchResult.failure(f"scan stamp {cloud.stamp} not after the reference's {self._ref_stamp}", n_points=n, gated=True)
        if self._velocity_stamp is not None and cloud.stamp - self._velocity_stamp > p.prior_max_age_s:
            self.velocity.reset()
        result = self._match(cloud, dt)
        result.n_points = n
        result.info["ref_stamp"] = self._ref_stamp  # T is relative to the lidar frame at this stamp
        if result.ok:
            overturned = ""
            reason = self._implausible(result.T, dt) or (overturned := self._overturned(result.T))
            if reason:
                result = MatchResult.failure(reason, n_points=n, **result.info)
            if overturned:
                # tracking restarts from this scan, taken as level as the first one was: a chain that tilted stays failed
                # otherwise (quickstart [fast] seed 0: every match after the Longfellow Bridge's deck, success 0.50)
                self._attitude = np.eye(3)
        if result.ok:
            self._attitude = self._attitude @ np.asarray(result.T, dtype=float)[:3, :3]
            self.velocity.update(result.T, dt, result.cov)
            self._velocity_stamp = cloud.stamp
        self._commit(result.ok)
        self._ref_stamp = cloud.stamp
        return result

    def _implausible(self, T: np.ndarray, dt: float) -> str:
        p = self.params
        xyzrpy = pose_to_xyzrpy(T)
        speed = float(np.linalg.norm(T[:3, 3])) / dt
        yaw_rate = abs(np.degrees(xyzrpy[5])) / dt
        if not np.isfinite(T).all():
            return "non-finite estimate"
        if speed > p.max_speed_mps:
            return f"implausible motion: {speed:.1f} m/s > max_speed_mps {p.max_speed_mps}"
        if yaw_rate > p.max_yaw_rate_dps:
            return f"implausible motion: yaw rate {yaw_rate:.1f} deg/s > max_yaw_rate_dps {p.max_yaw_rate_dps}"
        return ""

    def _overturned(self, T: np.ndarray) -> str:
        """Why the chained attitude after T is no boat's (tilted more than MAX_TILT_DEG from the first scan's), or ''.
        A rotation of pi about a horizontal axis turns the heading (Euler yaw) by 0 or 180 deg at once: the yaw-rate
        test passes the one about x; this one passes neither."""
        up = (self._attitude @ np.asarray(T, dtype=float)[:3, :3])[2, 2]  # the first frame's z in the new frame's z
        tilt = float(np.degrees(np.arccos(np.clip(up, -1.0, 1.0))))
        if tilt > MAX_TILT_DEG:
            return f"implausible attitude: chained odometry tilted {tilt:.0f} deg from the first scan's (> {MAX_TILT_DEG:g}: overturned)"
        return ""

    def _set_reference(self, cloud: Cloud) -> None:
        self._ref_stamp = cloud.stamp
        self._start(cloud)

    def _forget_reference(self) -> None:
        self._ref_stamp = self._velocity_stamp = None
        self.velocity.reset()
        self._reset()

    @abstractmethod
    def _start(self, cloud: Cloud) -> None:
        """Take `cloud` as the first reference."""

    @abstractmethod
    def _match(self, cloud: Cloud, dt: float) -> MatchResult:
        """Match `cloud` (dt s after the reference) and keep what `_commit` needs to make it the reference."""

    @abstractmethod
    def _commit(self, ok: bool) -> None:
        """Make the cloud just matched the reference (ok=False: its match failed; tracking restarts from it)."""

    @abstractmethod
    def _reset(self) -> None:
        """Drop all state (after an internal error)."""


class DeskewingMatcher(Matcher, Generic[P]):
    """A matcher whose reference is a scan prepared (de-skewed, filtered) with a motion prior (of type P).

    Keeps the reference and the scan just matched; a scan whose match failed is prepared again
    with the current prior before it becomes the reference, so that no reference is ever
    de-skewed with a failed estimate."""

    def __init__(self, params: MatcherParams) -> None:
        super().__init__(params)
        self._ref: P | None = None
        self._cur: P | None = None

    @abstractmethod
    def _prepare(self, cloud: Cloud, twist: np.ndarray | None) -> P:
        """`cloud` de-skewed with `twist` (per second; None: as it is) and made ready to match."""

    def _reference(self) -> P:
        """The prepared reference (`_start` sets it before any `_match`)."""
        assert self._ref is not None
        return self._ref

    def _start(self, cloud: Cloud) -> None:
        self._ref = self._prepare(cloud, None)

    def _reset(self) -> None:
        self._ref = self._cur = None

    def _commit(self, ok: bool) -> None:
        cur = self._cur
        assert cur is not None  # every _match keeps the scan it prepared
        if not ok and cur.twist is not self.velocity.twist_per_s:
            cur = self._prepare(cur.cloud, self.velocity.twist_per_s)
        self._ref, self._cur = cur, None
