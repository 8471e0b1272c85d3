"""MatchResult: what a scan matcher returns for one scan."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class MatchResult:
    """Relative motion of one scan.

    T: 4x4 pose of this scan's lidar frame at its stamp in the previous good scan's lidar frame at
    its stamp (identity when not ok). ok: the match is usable. cov: 6x6 covariance of
    [x, y, z, roll, pitch, yaw] in metres and radians, or None. n_points: points in the scan after
    the gate. seconds: wall time spent. info: diagnostics, always with 'reason' when not ok.
    """

    T: np.ndarray
    ok: bool
    cov: np.ndarray | None
    n_points: int
    seconds: float
    info: dict = field(default_factory=dict)

    @classmethod
    def failure(cls, reason: str, n_points: int = 0, seconds: float = 0.0, **info) -> "MatchResult":
        return cls(T=np.eye(4), ok=False, cov=None, n_points=n_points, seconds=seconds, info={"reason": reason, **info})
