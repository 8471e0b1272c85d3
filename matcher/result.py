"""MatchResult: what a scan matcher returns for one scan, and the check that a result is well formed."""

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
    def failure(cls, reason: str, n_points: int = 0, seconds: float = 0.0, **info) -> MatchResult:
        return cls(T=np.eye(4), ok=False, cov=None, n_points=n_points, seconds=seconds, info={"reason": reason, **info})


def checked(result: object) -> MatchResult:
    """`result` if it is a well-formed MatchResult (what every matcher, a plugin's too, must return), else a TypeError saying why."""
    if not isinstance(result, MatchResult):
        raise TypeError(f"register returned a {type(result).__name__}, not a matcher.MatchResult")
    try:
        T = np.asarray(result.T, dtype=float)
        cov = None if result.cov is None else np.asarray(result.cov, dtype=float)
        int(result.n_points), float(result.seconds)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"register returned a malformed MatchResult: {exc}") from None
    if T.shape != (4, 4):
        raise TypeError(f"register returned a MatchResult whose T has shape {T.shape}, not (4, 4)")
    if cov is not None and cov.shape != (6, 6):
        raise TypeError(f"register returned a MatchResult whose cov has shape {cov.shape}, not (6, 6)")
    if not isinstance(result.info, dict):
        raise TypeError(f"register returned a MatchResult whose info is a {type(result.info).__name__}, not a dict")
    return result
