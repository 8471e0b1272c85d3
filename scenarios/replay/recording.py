"""A recording opened for replay: where its time and ENU frame start, and its scans and fixes as a time-ordered stream.

Time: replay stamps are seconds since the scenario's UTC epoch (`[gnss] epoch_utc`) when the
recording starts within a day after it, as a simulated run's are (an exported run replays on its
own stamps); otherwise seconds since the recording's first message.
ENU: about the scenario's world origin when the recording's first position lies within
ORIGIN_RADIUS_M of it (a recording made on that world's river); otherwise about that first position.
Order: readers stamp every event from the recording's own header or packet times and release them
in stamp order (a scan before a fix at the same stamp, as in simulation) once REORDER_LAG_S of
recording has passed them, so a cloud logged after the fixes of its revolution still comes first.
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pymap3d

from riverbench.unixtime import UNIX_EPOCH, unix_ns
from scenarios.pipeline.feed import BadScan
from scenarios.pipeline.inertial import HeadingEvent, ImuEvent
from scenarios.pipeline.stream import ScanEvent
from scenarios.replay.imu import ImuReading
from sim.geodesy import LocalFrame
from sim.gnss_fix import GnssFix
from sim.nmea.epochs import Tally

DAY_NS = 86_400 * 10**9
ORIGIN_RADIUS_M = 20_000.0
REORDER_LAG_S = 1.0


@dataclass(frozen=True)
class RecordedFix:
    """A receiver epoch read from a recording: the fix as the estimators take it, and the NMEA sentences it came from (if any)."""

    stamp: float
    fix: GnssFix
    sentences: tuple[str, ...] = ()


Event = ScanEvent | RecordedFix | BadScan | ImuEvent | HeadingEvent


@dataclass(frozen=True)
class Place:
    """What a reader takes from the scenario: world origin, UTC epoch, lidar revolution start (deg CCW from its x)."""

    origin: tuple[float, float, float]
    epoch_utc: datetime
    start_azimuth_deg: float = 180.0
    imu_noise: tuple[float, float] | None = None
    """The scenario's IMU white-noise densities (gyro rad/s/sqrt(Hz), accel m/s^2/sqrt(Hz)) when an estimator is fed
    the IMU (then a bag's sensor_msgs/Imu is read), else None."""
    compass_sigma: float | None = None
    """The scenario's compass heading accuracy (rad) when an estimator is fed the compass (then a bag's AHRS
    orientation and field are read, scenarios.replay.compass), else None."""


@dataclass(frozen=True)
class Geo:
    """The replay's time zero (ns since the Unix epoch) and ENU frame, fixed from the recording's first message and position."""

    zero_ns: int
    origin: tuple[float, float, float]
    origin_source: str
    frame: LocalFrame = field(repr=False)

    @classmethod
    def choose(cls, place: Place, first_ns: int, first_position: tuple[float, float, float] | None) -> Geo:
        """Time zero and ENU origin by the rules of the module docstring."""
        epoch = unix_ns(place.epoch_utc)
        zero = epoch if 0 <= first_ns - epoch < DAY_NS else first_ns
        origin, source = tuple(place.origin), "world"
        if first_position is not None and distance_m(place.origin, first_position) > ORIGIN_RADIUS_M:
            origin, source = tuple(first_position), "first fix"
        return cls(zero, origin, source, LocalFrame.at(*origin))

    def seconds(self, ns: int) -> float:
        """Replay time of a recording time in integer nanoseconds since the Unix epoch."""
        return (ns - self.zero_ns) / 1e9

    def enu(self, lat: float, lon: float, alt: float) -> np.ndarray:
        """ENU metres of a WGS-84 position (NaN when it has none)."""
        if not (math.isfinite(lat) and math.isfinite(lon) and math.isfinite(alt)):
            return np.full(3, np.nan)
        return self.frame.enu_of_ecef(np.array(pymap3d.geodetic2ecef(lat, lon, alt)))

    def utc(self, stamp: float) -> datetime:
        """The UTC time of a replay stamp (to the microsecond)."""
        return UNIX_EPOCH + timedelta(microseconds=self.zero_ns // 1000 + round(stamp * 1e6))


def distance_m(a: tuple[float, float, float], b: tuple[float, float, float]) -> float:
    """Straight-line distance between two WGS-84 positions."""
    return float(np.linalg.norm(np.subtract(pymap3d.geodetic2ecef(*a), pymap3d.geodetic2ecef(*b))))


@dataclass
class LogStats:
    """What reading NMEA sentences counted: lines read and skipped (sim.nmea.epochs.Tally), epochs, those with a fix, and
    those set aside from the log's clock (scenarios.replay.nmea_log): before the first fix, jumps of more than a day, and
    out of time order."""

    tally: Tally = field(default_factory=Tally)
    epochs: int = 0
    with_fix: int = 0
    before_first_fix: int = 0
    clock_jumps: int = 0
    out_of_order: int = 0

    def summary(self) -> str:
        """One line for the user."""
        aside = [
            f"{self.before_first_fix} before the first fix" if self.before_first_fix else "",
            f"{self.clock_jumps} jumping more than a day" if self.clock_jumps else "",
            f"{self.out_of_order} out of time order" if self.out_of_order else "",
        ]
        said = ", ".join(a for a in aside if a)
        return f"{self.tally.summary()}; {self.epochs} epochs, {self.with_fix} with a fix" + (f"; epochs set aside: {said}" if said else "")

    def tree(self) -> dict:
        """The counts as metrics.json holds them."""
        return {
            "read": dict(sorted(self.tally.read.items())),
            "read_without_checksum": self.tally.unchecked,
            "skipped": dict(self.tally.skipped.most_common()),
            "epochs": self.epochs,
            "with_fix": self.with_fix,
            "before_first_fix": self.before_first_fix,
            "clock_jumps": self.clock_jumps,
            "out_of_order": self.out_of_order,
        }


@dataclass(frozen=True)
class Recording:
    """An opened recording: what was picked from it (lidar_source '' when it has no LiDAR: a GNSS-only replay), its time
    span in replay seconds, its events (read lazily, once), when its GPS is NMEA, what reading it counted (filled as the
    events are read), and its IMU topic and mount ('' when no IMU is read)."""

    path: Path
    format: str
    lidar_source: str
    gps_source: str
    geo: Geo
    t_start: float
    t_end: float
    events: Callable[[], Iterator[Event]] = field(repr=False)
    nmea: LogStats | None = field(default=None, repr=False)
    imu_source: str = ""
    compass_source: str = ""
    facts: dict = field(default_factory=dict)
    """What the reader found that a report should state (a capture's sensor, clocks, revolutions, fixes in the file)."""

    @property
    def gnss_only(self) -> bool:
        """No LiDAR: the estimators run on the fixes alone."""
        return not self.lidar_source


class TimeOrder:
    """Events released in stamp order, once the recording has moved past them; at the same stamp an IMU sample, then a
    compass heading, then a scan, then a fix or failure (a run's IMU batch and heading up to a scan come before it)."""

    def __init__(self) -> None:
        self._heap: list[tuple[float, int, int, Event | ImuReading]] = []
        self._seq = itertools.count()

    def add(self, event: Event | ImuReading) -> None:
        """Hold an event until its turn."""
        rank = 0 if isinstance(event, ImuReading) else 1 if isinstance(event, HeadingEvent) else 2 if isinstance(event, ScanEvent) else 3
        heapq.heappush(self._heap, (event.stamp, rank, next(self._seq), event))

    def release(self, before: float) -> Iterator[Event | ImuReading]:
        """The held events stamped before `before`, in order."""
        while self._heap and self._heap[0][0] < before:
            yield heapq.heappop(self._heap)[3]

    def rest(self) -> Iterator[Event | ImuReading]:
        """Every held event, in order (the recording ended)."""
        return self.release(math.inf)
