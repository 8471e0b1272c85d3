"""What every export writes: a scenario's simulated sensor stream, one LiDAR revolution at a time.

A Frame is a revolution with the receiver outputs that fall inside it, the exact poses at its
stamp and, when asked for, each estimator's output at that stamp. `open_stream(scenario)` simulates
them lazily (no matcher, no estimator in open loop unless `estimates`), so an export of the whole
charles_river route streams in constant memory. The same seed gives the same frames, and the same
estimates, as `riverbench run` of that scenario.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import datetime

import numpy as np

from riverbench.samples import HeadingSample, ImuSamples
from scenarios.pipeline.assembly import assemble, matcher_setups
from scenarios.pipeline.assembly import recorder as make_recorder
from scenarios.pipeline.feed import Feed
from scenarios.pipeline.inertial import HeadingEvent, ImuEvent
from scenarios.pipeline.matcher_pool import MatcherPool
from scenarios.pipeline.stream import ScanEvent
from scenarios.pipeline.vessel_run import VesselRun
from scenarios.spec.scenario import Scenario
from sim.gnss_fix import GnssFix
from sim.scan import Scan


@dataclass(frozen=True)
class Estimate:
    """An estimator's output at a scan's stamp: pose world<-base_link (4x4) and covariance (6x6 [x, y, z, roll, pitch,
    yaw], scenarios.pipeline.feed.Feed.cov_of; None when the estimator gives none)."""

    pose: np.ndarray
    cov: np.ndarray | None


@dataclass(frozen=True)
class Frame:
    """One revolution: the scan (points in the lidar frame at their firing times, as the sensor reports
    them), the true poses world<-base_link and world<-lidar at its stamp, the fixes with
    stamp in [this scan's stamp, the next scan's stamp), and, when the stream runs the estimators,
    each initialised estimator's output at this scan by id (in the scenario's order), and, when the scenario simulates
    them, the IMU's batches and the compass's outputs that came after the scan (before the first scan: with it)."""

    index: int
    scan: Scan
    base_pose: np.ndarray
    lidar_pose: np.ndarray
    fixes: list[GnssFix] = field(default_factory=list)
    estimates: dict[str, Estimate] = field(default_factory=dict)
    imu: list[ImuSamples] = field(default_factory=list)
    headings: list[HeadingSample] = field(default_factory=list)

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
    estimators: tuple[str, ...] = ()
    inertial: InertialInfo | None = None


@dataclass(frozen=True)
class InertialInfo:
    """The simulated IMU (and compass) as a driver describes them: rate, datasheet white-noise densities, the IMU's
    position on base_link (its axes are base_link's, sim.imu) and the magnetometer's noise (None: no compass)."""

    rate_hz: float
    gyro_noise: float
    accel_noise: float
    lever_m: tuple[float, float, float]
    compass_noise_ut: float | None = None


def open_stream(scenario: Scenario, estimates: bool = False) -> tuple[StreamInfo, Iterator[Frame]]:
    """The stream's description and its frames (simulated lazily, as the iterator is consumed).

    With `estimates` the scenario's matchers and estimators run as `riverbench run` runs them (in this
    process) and each frame carries their outputs; `info.estimators` names them. A closed-loop scenario
    is always driven so (the autopilot steers on one); `scans` is then the planned count, an upper
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
        tuple(e.id for e in scenario.estimators) if estimates else (),
        inertial_info(scenario, run),
    )
    if run.loop is None and not estimates:
        return info, _frames(run.events(None), run.trajectory, lambda frame: None)
    return info, _estimated_frames(scenario, run, t_start, estimates)


def inertial_info(scenario: Scenario, run: VesselRun) -> InertialInfo | None:
    """What the IMU's and compass's topics need, when the scenario simulates an IMU (an estimator is fed it)."""
    if run.imu is None or scenario.imu is None:
        return None
    compass = scenario.compass.noise_ut if scenario.compass is not None and run.compass is not None else None
    return InertialInfo(scenario.imu.rate_hz, run.imu.gyro_noise_density, run.imu.accel_noise_density, tuple(scenario.imu.lever_m), compass)


def _estimated_frames(scenario: Scenario, run: VesselRun, t_start: float, estimates: bool) -> Iterator[Frame]:
    """The frames with the run's events also fed through the scenario's matchers and estimators (which steer a closed
    loop); with `estimates` each frame gets their outputs at its scan, read once they have that scan and nothing later."""
    awaiting: deque[Frame] = deque()  # frames whose scan the estimators have not had yet, oldest first

    def record(stamp: float, results: dict) -> None:
        """The estimators have the scan of the oldest awaiting frame: keep each initialised one's pose and covariance."""
        frame = awaiting.popleft()
        for eid in feed.estimators if estimates else ():
            pose = feed.pose_of(eid)
            if np.isfinite(pose).all():
                frame.estimates[eid] = Estimate(pose, feed.cov_of(eid))

    with MatcherPool(matcher_setups(scenario), workers=1) as pool:
        recorder = make_recorder(scenario, run.trajectory.mount)
        feed = Feed(scenario, pool, recorder, run.trajectory.pose, t_start, on_scan=record)

        def fed() -> Iterator:
            for event in run.events(feed):
                feed.push(event)
                yield event
            feed.finish()

        yield from _frames(fed(), run.trajectory, awaiting.append)


def _frames(events: Iterator, trajectory, created: Callable[[Frame], None]) -> Iterator[Frame]:
    """Group the time-ordered events into frames: each scan with the fixes up to the next scan; created(frame) as each
    frame is made, and a frame is yielded only once the next scan's event (or the end) has come."""
    current: Frame | None = None
    pending: list[GnssFix] = []  # fixes, IMU batches and headings before the first scan go with it
    imu: list[ImuSamples] = []
    headings: list[HeadingSample] = []
    for event in events:
        if isinstance(event, ScanEvent):
            if current is not None:
                yield current
            index = 0 if current is None else current.index + 1
            current = Frame(index, event.scan, trajectory.pose(event.stamp), trajectory.lidar_pose(event.stamp), pending, imu=imu, headings=headings)
            created(current)
            pending, imu, headings = [], [], []
        elif isinstance(event, ImuEvent):
            (imu if current is None else current.imu).append(event.samples)
        elif isinstance(event, HeadingEvent):
            (headings if current is None else current.headings).append(event.sample)
        elif hasattr(event, "fix"):
            (pending if current is None else current.fixes).append(event.fix)
    if current is not None:
        yield current
