"""Monitor interface: judge each fix from what the filter and the odometry say about it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fusion.observation import FixObservation
from fusion.odometry import OdometryTrack
from fusion.verdict import Verdict


@dataclass(frozen=True)
class FixContext:
    """What the host estimator knows when a fix arrives.

    predicted: the fix (x, y) the filter expects, the 2x2 covariance of that prediction and the 2x2
    noise it assumes for this fix (None before it is initialised); yaw/yaw_var: the filter's heading and its variance (None before initialisation);
    lever: antenna (x, y) on base_link; odometry: the scan-matching chain; correlation_s: the
    receiver's error time constant (see EstimatorParams.gps_correlation_s); velocity: the filter's horizontal
    velocity of base_link in the world, m/s (None before initialisation, or for a filter without one); velocity_cov: its
    2x2 covariance, (m/s)^2, with the heading's share (None where the filter keeps none); own_start: the filter started
    from a position of its own (a given initial pose), not from the fixes, and no re-lock has moved it onto one since.
    """

    predicted: tuple[np.ndarray, np.ndarray, np.ndarray] | None
    yaw: float | None
    yaw_var: float | None
    lever: np.ndarray
    odometry: OdometryTrack
    correlation_s: float = 0.0
    velocity: np.ndarray | None = None
    antenna: np.ndarray | None = None
    velocity_cov: np.ndarray | None = None
    own_start: bool = False


def mahalanobis2(r: np.ndarray, cov: np.ndarray) -> float:
    """r' cov^-1 r, or NaN when cov is not finite or not invertible (never raises)."""
    if not (np.all(np.isfinite(cov)) and np.all(np.isfinite(r))):
        return float("nan")
    try:
        return float(r @ np.linalg.solve(cov, r))
    except np.linalg.LinAlgError:
        return float("nan")


class Monitor:
    """A GPS integrity monitor. check() has no side effects; commit() records the final decision."""

    name = "monitor"
    wants_scans = False
    """Whether add_scan should be fed the host's scans (a monitor that maps what the LiDAR sees)."""

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        raise NotImplementedError

    def commit(self, obs: FixObservation, verdict: Verdict) -> None:
        """Record the decision the estimator acted on (a combination may overrule this monitor)."""

    def reset(self) -> None:
        """Forget the history (the host re-locked onto GPS)."""

    def add_scan(self, stamp: float, pose: np.ndarray, points: np.ndarray) -> None:
        """One LiDAR scan's points (N, 3) in base_link, with the host's pose (4x4 world<-base_link) at its stamp; only
        called when wants_scans."""

    def note_outage(self, stamp: float) -> None:
        """An epoch without a measured position (no fix, dead reckoning or a bad field)."""
