"""The simulated sensor stream: LiDAR scans and GNSS fixes generated lazily in time order (what the Feed consumes).

Nothing holds the run: each scan is simulated when it is asked for and dropped after it is matched, so memory stays
flat in scenario length.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from riverbench.unixtime import on_ns_grid
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
    return on_ns_grid(t_start + np.arange(n) * lidar.revolution_s)


def events(
    world, trajectory, lidar, receiver, t_start: float = 0.0, t_end: float | None = None, cast: Callable[[float], Scan] | None = None
) -> Iterator[ScanEvent | FixEvent]:
    """Scans and fixes over [t_start, t_end) (default: the whole trajectory) in time order, lazily; `cast(t)`, when given,
    gives the revolution at t in place of the lidar (scenarios.pipeline.scan_ahead: the same one, cast ahead in a worker).

    A scan is stamped with its revolution start; at equal stamps the scan comes first. The
    receiver is asked for fixes at increasing times, as its internal filter requires. Every time is on the
    nanosecond grid, so a bag of the run replays with the very same times.
    """
    t_end = trajectory.duration if t_end is None else float(t_end)
    if not (math.isfinite(t_start) and math.isfinite(t_end) and 0.0 <= t_start < t_end <= trajectory.duration + 1e-9):
        raise ValueError(f"stream: need 0 <= t_start < t_end <= duration {trajectory.duration:.2f} s, got [{t_start}, {t_end}]")
    scans = ((float(t), 0, "scan") for t in scan_times(lidar, t_start, t_end))
    fixes = ((float(t), 1, "fix") for t in on_ns_grid(receiver.epochs(t_end, t_start)))
    for t, _, kind in heapq.merge(scans, fixes):
        if kind == "scan":
            yield ScanEvent(t, lidar.scan(world, trajectory, t) if cast is None else cast(t))
        else:
            yield FixEvent(t, receiver.fix(world, trajectory, t))


def pose_xyzyaw(T: np.ndarray) -> np.ndarray:
    """(x, y, z, yaw) of a 4x4 world<-base_link pose."""
    return np.array([T[0, 3], T[1, 3], T[2, 3], math.atan2(T[1, 0], T[0, 0])])


__all__ = ["FixEvent", "ScanEvent", "events", "pose_xyzyaw", "scan_times"]
