"""What every export writes: a scenario's simulated sensor stream, one LiDAR revolution at a time.

A Frame is a revolution with the receiver outputs that fall inside it and the exact poses at its
stamp. `frames(scenario)` simulates them lazily (no matcher, no estimator in open loop), so an export of the
whole charles_river route streams in constant memory. The same seed gives the same frames as
`riverbench run` of that scenario.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from datetime import datetime

import numpy as np

from scenarios.pipeline.assembly import assemble, matcher_setups
from scenarios.pipeline.assembly import recorder as make_recorder
from scenarios.pipeline.feed import Feed
from scenarios.pipeline.matcher_pool import MatcherPool
from scenarios.pipeline.stream import ScanEvent
from scenarios.pipeline.vessel_run import VesselRun
from scenarios.spec.scenario import Scenario
from sim.gnss_fix import GnssFix
from sim.scan import Scan


@dataclass(frozen=True)
class Frame:
    """One revolution: the scan (points in the lidar frame at their firing times, as the sensor reports
    them), the true poses world<-base_link and world<-lidar at its stamp, and the fixes with
    stamp in [this scan's stamp, the next scan's stamp)."""

    index: int
    scan: Scan
    base_pose: np.ndarray
    lidar_pose: np.ndarray
    fixes: list[GnssFix] = field(default_factory=list)

    @property
    def stamp(self) -> float:
        return self.scan.stamp


@dataclass(frozen=True)
class StreamInfo:
    """What a format needs besides the frames: names, rates, geodesy, time base and the boat's fixed transforms."""

    scenario: str
    t_start: float
    t_end: float
    scans: int
    lidar_rate_hz: float
    gnss_rate_hz: float
    origin: tuple[float, float, float]
    epoch_utc: datetime
    mount: np.ndarray
    antenna_offset_m: tuple[float, float, float]


def open_stream(scenario: Scenario) -> tuple[StreamInfo, Iterator[Frame]]:
    """The stream's description and its frames (simulated lazily, as the iterator is consumed).

    A closed-loop scenario is driven as `riverbench run` drives it (its matchers and estimators run
    in this process so the autopilot can steer on one); `scans` is then the planned count, an upper
    bound when the vessel stops early (a collision).
    """
    stack = assemble(scenario)
    world, lidar, run, t_start, t_end = stack.world, stack.lidar, stack.vessel_run, stack.t_start, stack.t_end
    n_scans = int(np.floor((t_end - t_start) / lidar.revolution_s + 1e-9))
    info = StreamInfo(
        scenario.name,
        t_start,
        t_end,
        n_scans,
        scenario.lidar.rate_hz,
        scenario.gnss.rate_hz,
        tuple(world.origin),
        scenario.gnss.epoch_utc,
        run.trajectory.mount.copy(),
        tuple(scenario.gnss.antenna_offset_m),
    )
    return info, _frames(_events(scenario, run, t_start), run.trajectory)


def _events(scenario: Scenario, run: VesselRun, t_start: float) -> Iterator:
    """The run's events; in closed loop each also goes through the scenario's matchers and estimators, which steer it."""
    if run.loop is None:
        yield from run.events(None)
        return
    with MatcherPool(matcher_setups(scenario), workers=1) as pool:
        recorder = make_recorder(scenario, run.trajectory.mount)
        feed = Feed(scenario, pool, recorder, run.trajectory.pose, t_start)
        for event in run.events(feed):
            feed.push(event)
            yield event


def _frames(events: Iterator, trajectory) -> Iterator[Frame]:
    """Group the time-ordered events into frames: each scan with the fixes up to the next scan."""
    current: Frame | None = None
    pending: list[GnssFix] = []  # fixes before the first scan go with it
    for event in events:
        if not hasattr(event, "scan") and not hasattr(event, "fix"):
            continue  # IMU and compass outputs are not exported yet
        if isinstance(event, ScanEvent):
            if current is not None:
                yield current
            index = 0 if current is None else current.index + 1
            current = Frame(index, event.scan, trajectory.pose(event.stamp), trajectory.lidar_pose(event.stamp), pending)
            pending = []
        elif current is None:
            pending.append(event.fix)
        else:
            current.fixes.append(event.fix)
    if current is not None:
        yield current
