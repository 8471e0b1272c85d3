"""IMU samples and compass headings woven into a run's stream of scans and fixes, in time order.

Before each scan or fix event the IMU's samples since the previous event arrive as one batch (so a filter has
its gyro up to the moment it is asked for a pose or judges a fix), and the compass's outputs in that interval
one event each. Works on any event iterator whose trajectory is known up to each event's stamp (open loop, and
closed loop, where the vessel is driven a revolution ahead of its scan).
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from riverbench.samples import HeadingSample, ImuSamples


@dataclass(frozen=True)
class ImuEvent:
    """The IMU's samples in (previous event, stamp]."""

    stamp: float
    samples: ImuSamples


@dataclass(frozen=True)
class HeadingEvent:
    """One compass output; `truth_yaw` is the true heading, for the metrics only (never given to a filter)."""

    stamp: float
    sample: HeadingSample
    truth_yaw: float


def with_inertial(events: Iterator, trajectory, imu=None, compass=None, t_start: float = 0.0) -> Iterator:
    """`events` with ImuEvents and HeadingEvents put before each one (none when imu and compass are None)."""
    if imu is None and compass is None:
        yield from events
        return
    last = float(t_start)
    for event in events:
        stamp = float(event.stamp)
        if stamp > last:
            yield from _between(trajectory, imu, compass, last, stamp)
            last = stamp
        yield event


def _between(trajectory, imu, compass, t0: float, t1: float) -> Iterator:
    """The sensors' outputs in (t0, t1] in time order: before each compass output the IMU batch up to it, then the rest
    of the batch up to t1 (a batch is stamped at its last sample)."""
    headings: list[tuple[float, HeadingSample, float]] = []
    if compass is not None:
        ts = compass.times(t0, t1)
        if len(ts):
            truth = trajectory.poses(ts)
            headings = [(float(s.stamp), s, float(np.arctan2(p[1, 0], p[0, 0]))) for s, p in zip(compass.read(trajectory, ts), truth)]
    last = t0
    for stamp, sample, truth_yaw in headings:
        yield from _imu_batch(trajectory, imu, last, stamp)
        last = stamp
        yield HeadingEvent(stamp, sample, truth_yaw)
    yield from _imu_batch(trajectory, imu, last, t1)


def _imu_batch(trajectory, imu, t0: float, t1: float) -> Iterator:
    if imu is not None and t1 > t0:
        ts = imu.times(t0, t1)
        if len(ts):
            yield ImuEvent(float(ts[-1]), imu.sample(trajectory, ts))


__all__ = ["HeadingEvent", "ImuEvent", "with_inertial"]
