"""Streaming scenario driver: LiDAR scans and GNSS fixes generated lazily in time order, and a small
helper that drives matchers and fusion estimators over them and keeps estimates against truth.

Nothing holds the run: each scan is simulated, matched and dropped; only per-time estimates (a few
numbers per scan and per fix) are kept, so memory stays flat in scenario length up to those.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field

import numpy as np

from sim.gnss_fix import GnssFix
from sim.scan import Scan


@dataclass(frozen=True)
class ScanEvent:
    """A LiDAR revolution that started at `stamp`."""

    stamp: float
    scan: Scan


@dataclass(frozen=True)
class FixEvent:
    """A receiver output epoch at `stamp`."""

    stamp: float
    fix: GnssFix


def scan_times(lidar, t_start: float, t_end: float) -> np.ndarray:
    """Revolution start times whose whole revolution lies in [t_start, t_end]."""
    n = int(math.floor((t_end - t_start) / lidar.revolution_s + 1e-9))
    return t_start + np.arange(n) * lidar.revolution_s


def events(world, trajectory, lidar, receiver, t_start: float = 0.0, t_end: float | None = None) -> Iterator[ScanEvent | FixEvent]:
    """Scans and fixes over [t_start, t_end) (default: the whole trajectory) in time order, lazily.

    A scan is stamped with its revolution start; at equal stamps the scan comes first. The
    receiver is asked for fixes at increasing times, as its internal filter requires.
    """
    t_end = trajectory.duration if t_end is None else float(t_end)
    if not (math.isfinite(t_start) and math.isfinite(t_end) and 0.0 <= t_start < t_end <= trajectory.duration + 1e-9):
        raise ValueError(f"stream: need 0 <= t_start < t_end <= duration {trajectory.duration:.2f} s, got [{t_start}, {t_end}]")
    scans = ((float(t), 0, "scan") for t in scan_times(lidar, t_start, t_end))
    fixes = ((float(t), 1, "fix") for t in receiver.epochs(t_end, t_start))
    for t, _, kind in heapq.merge(scans, fixes):
        if kind == "scan":
            yield ScanEvent(t, lidar.scan(world, trajectory, t))
        else:
            yield FixEvent(t, receiver.fix(world, trajectory, t))


def pose_xyzyaw(T: np.ndarray) -> np.ndarray:
    """(x, y, z, yaw) of a 4x4 world<-base_link pose."""
    return np.array([T[0, 3], T[1, 3], T[2, 3], math.atan2(T[1, 0], T[0, 0])])


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


__all__ = ["FixEvent", "ScanEvent", "Track", "drive", "events", "pose_xyzyaw", "scan_times"]
