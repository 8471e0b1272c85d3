"""The closed loop: the vessel driven one LiDAR revolution at a time by thruster commands.

Each period the commands (from the autopilot steering on an estimator's pose, or from an agent)
are held for one revolution: the WAM-V model is integrated over it, the hull is checked against
the world, and the revolution's scan and the receiver's fixes inside it are simulated from the
driven motion. The loop ends when the vessel reaches the end of its stretch, touches a structure
(a recorded outcome, never an exception) or runs out of time.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import numpy as np

from riverbench.unixtime import on_ns_grid
from scenarios.pipeline.stream import FixEvent, ScanEvent
from scenarios.score.vessel_log import VesselWatch
from sim.autopilot import Autopilot
from sim.driven_trajectory import DrivenTrajectory
from sim.scan import Scan


class ClosedLoop:
    """`step(commands)` drives one revolution and returns its events (scan first, then the fixes in it)."""

    def __init__(
        self, world, trajectory: DrivenTrajectory, lidar, receiver, watch: VesselWatch, t_start: float, end_station_m: float, t_limit: float
    ):
        self.world, self.trajectory, self.lidar, self.receiver, self.watch = world, trajectory, lidar, receiver, watch
        self.t = float(on_ns_grid(t_start))
        self.t_start, self.end_station_m, self.t_limit = float(t_start), float(end_station_m), float(t_limit)
        self._fixes = 0
        self._periods = 0
        self.cast: Callable[[float], Scan] | None = None
        """The revolution at t in place of the LiDAR's, when set (scenarios.pipeline.runner: stamps alone when nothing reads
        a revolution's points)."""

    @property
    def done(self) -> bool:
        return self.watch.log.outcome != "interrupted"

    @property
    def station_m(self) -> float:
        """Route station of the true position now."""
        return float(self.world.route.project(self.trajectory.pose(self.t)[:2, 3])[0])

    def step(self, commands: tuple[float, float]) -> list[ScanEvent | FixEvent]:
        """Hold `commands` (left, right in [-1, 1]) for one revolution; the scan and fixes it produced."""
        if self.done:
            raise RuntimeError(f"closed loop: the run has ended ({self.watch.log.outcome})")
        # times from counters (as the open-loop stream's), so scan and fix stamps never drift apart by rounding
        t0, t1 = self.t, float(on_ns_grid(self.t_start + (self._periods + 1) * self.lidar.revolution_s))
        self.trajectory.drive(commands, t1)
        contact = self.watch.period(t0, t1, commands)
        events: list[ScanEvent | FixEvent] = []
        if contact is None:
            events.append(ScanEvent(t0, self.lidar.scan(self.world, self.trajectory, t0) if self.cast is None else self.cast(t0)))
        until = t1 if contact is None else contact.t
        while (t_fix := float(on_ns_grid(self.t_start + self._fixes / self.receiver.rate_hz))) < until:
            events.append(FixEvent(t_fix, self.receiver.fix(self.world, self.trajectory, t_fix)))
            self._fixes += 1
        self.t = t1
        self._periods += 1
        if contact is None:
            if self.station_m >= self.end_station_m:
                self.watch.log.outcome = "completed"
            elif t1 + self.lidar.revolution_s > self.t_limit + 1e-9:
                self.watch.log.outcome = "time_limit"
        return events


def autopiloted(loop: ClosedLoop, autopilot: Autopilot, steer: Callable[[float], tuple[np.ndarray, float | None]]) -> Iterator[ScanEvent | FixEvent]:
    """The loop's events with the autopilot steering on `steer(t)`: the pose and gyro yaw rate (or None) it is given at each period start."""
    while not loop.done:
        yield from loop.step(autopilot.commands(loop.t, *steer(loop.t)))


def watched(events: Iterator, watch: VesselWatch, revolution_s: float) -> Iterator:
    """Open loop: the stream's events, the hull checked at each scan; the stream stops at a contact."""
    for event in events:
        if isinstance(event, ScanEvent) and watch.period(event.stamp, event.stamp + revolution_s) is not None:
            return
        yield event
    watch.log.outcome = "completed"
