"""The tests' in-process drive: matchers and estimators over the simulated stream, every estimate kept against truth.

Runs use scenarios.pipeline.feed (a matcher process beside the simulation, estimates reduced as they come);
fusion tests want every pose and covariance in memory, which this keeps.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from scenarios.pipeline.stream import ScanEvent, events, pose_xyzyaw


@dataclass
class Track:
    """What a drive keeps: per scan, truth and every estimate; per fix, its truth and every verdict.

    scan_stamp (N,); truth (N, 4) x, y, z, yaw of base_link; estimate[name] (N, 4) and cov[name]
    (N, 3, 3) of (x, y, yaw) after that scan; match_ok[matcher] (N,) bool. fix_stamp (M,);
    fix_error (M,) true horizontal error (NaN without a position); fix_quality, fix_hdop (M,);
    trusted[name] (M,) bool and statistic[name] (M,) per estimator.
    """

    scan_stamp: np.ndarray
    truth: np.ndarray
    estimate: dict[str, np.ndarray]
    cov: dict[str, np.ndarray]
    match_ok: dict[str, np.ndarray]
    fix_stamp: np.ndarray
    fix_error: np.ndarray
    fix_quality: np.ndarray
    fix_hdop: np.ndarray
    trusted: dict[str, np.ndarray]
    statistic: dict[str, np.ndarray]

    def error(self, name: str) -> np.ndarray:
        """(N,) horizontal error of an estimator at the scan times (NaN before it is initialised)."""
        return np.hypot(*(self.estimate[name][:, :2] - self.truth[:, :2]).T)


@dataclass
class _Columns:
    rows: dict[str, list] = field(default_factory=dict)

    def add(self, key: str, value) -> None:
        self.rows.setdefault(key, []).append(value)

    def array(self, key: str, empty_shape: tuple = (0,), dtype=float) -> np.ndarray:
        values = self.rows.get(key)
        return np.asarray(values, dtype=dtype) if values else np.zeros(empty_shape, dtype=dtype)


def drive(
    world,
    trajectory,
    lidar,
    receiver,
    matchers: Mapping[str, object],
    estimators: Mapping[str, object],
    t_start: float = 0.0,
    t_end: float | None = None,
    on_event=None,
) -> Track:
    """Run matchers and estimators over the stream; each estimator gets its own matcher's results.

    matchers: name -> object with register(scan) -> MatchResult; estimators: name -> fusion
    Estimator (its params.matcher must be among `matchers` when it uses odometry). on_event, if
    given, is called with each event (e.g. to advance a progress bar).
    """
    for name, est in estimators.items():
        wanted = est.params.matcher
        if getattr(est, "uses_odometry", True) and wanted not in matchers:
            raise ValueError(f"stream: estimator '{name}' uses matcher '{wanted}', not among the matchers given ({', '.join(matchers) or 'none'})")
    cols = _Columns()
    for event in events(world, trajectory, lidar, receiver, t_start, t_end):
        if isinstance(event, ScanEvent):
            results = {m: matcher.register(event.scan) for m, matcher in matchers.items()}
            for name, est in estimators.items():
                if getattr(est, "uses_odometry", True):
                    est.add_match(event.stamp, results[est.params.matcher])
                cols.add(f"est:{name}", pose_xyzyaw(est.pose))
                cols.add(f"cov:{name}", est.cov)
            for m, result in results.items():
                cols.add(f"ok:{m}", bool(result.ok))
            cols.add("scan_stamp", event.stamp)
            cols.add("truth", pose_xyzyaw(trajectory.pose(event.stamp)))
        else:
            fix = event.fix
            for name, est in estimators.items():
                verdict = est.add_fix(fix)
                cols.add(f"trusted:{name}", bool(verdict.trusted))
                cols.add(f"stat:{name}", float(verdict.statistic))
            error = fix.truth.error if fix.truth is not None else None
            cols.add("fix_stamp", event.stamp)
            cols.add("fix_error", float(np.hypot(error[0], error[1])) if error is not None and fix.quality else math.nan)
            cols.add("fix_quality", int(fix.quality))
            cols.add("fix_hdop", float(fix.hdop))
        if on_event is not None:
            on_event(event)
    return Track(
        scan_stamp=cols.array("scan_stamp"),
        truth=cols.array("truth", (0, 4)),
        estimate={n: cols.array(f"est:{n}", (0, 4)) for n in estimators},
        cov={n: cols.array(f"cov:{n}", (0, 3, 3)) for n in estimators},
        match_ok={m: cols.array(f"ok:{m}", dtype=bool) for m in matchers},
        fix_stamp=cols.array("fix_stamp"),
        fix_error=cols.array("fix_error"),
        fix_quality=cols.array("fix_quality", dtype=int),
        fix_hdop=cols.array("fix_hdop"),
        trusted={n: cols.array(f"trusted:{n}", dtype=bool) for n in estimators},
        statistic={n: cols.array(f"stat:{n}") for n in estimators},
    )
