"""One timeline for a Velodyne capture, from its three clocks, all in integer nanoseconds.

- The sensor's clock: each data and position packet carries the microseconds past the top of the hour of its
  first firing (or of its sending); it is exact between packets (the firing timing is built on it). Its hour
  is the capture clock's at the first packet (within half an hour of it), and it counts on across each top of
  the hour. With a locked PPS (position packets' status 2) it is UTC; without one it runs free from wherever
  the sensor started it (the VLP-16 capture's is 1431 s off its capture clock).
- The capture clock: the host's record times, UTC as far as the host's own clock is, late by the network.
- GNSS time: each GPRMC the position packets relay is stamped with its epoch's UTC by the receiver; it reaches
  the sensor some time after that epoch (the receiver's output delay) and stays in every position packet until
  the next one arrives.

The timeline is UTC: the sensor's clock with a locked PPS; else, when position packets relay GPRMC, the sensor's
clock minus its offset to GNSS time, measured as the smallest (first arrival on the sensor clock - epoch) over
the sentences whose arrival the capture holds (an offset that takes the receiver's output delay as zero; with no
arrival in the capture, the first sentence's age at the first packet bounds it); else the capture clock, i.e.
the sensor's clock plus the median (capture - sensor) over the data packets. Scans are stamped on it through the
sensor's clock; each fix at its own epoch, which is never after its arrival, so a reader that holds events for
`lag_ns` (the latest arrival after the epoch, plus two revolutions) drops none.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

HOUR_NS = 3_600 * 10**9
HALF_HOUR_NS = HOUR_NS // 2
SAMPLE_EVERY = 16
"""Data packets whose (capture - sensor) offset is kept for its median: one in this many (memory stays flat)."""
PPS_LOCKED = 2
PPS_STATUS = {0: "absent", 1: "synchronizing", PPS_LOCKED: "locked", 3: "error"}


class SensorClock:
    """A sensor's microseconds past the hour as nanoseconds since the Unix epoch (see the module docstring)."""

    def __init__(self) -> None:
        self._hour_ns: int | None = None
        self._last_ns = 0

    def ns(self, usec_past_hour: int, capture_ns: int) -> int:
        """The packet's sensor time, given its capture time (which places the first packet's hour only)."""
        past = int(usec_past_hour) * 1000
        if self._hour_ns is None:
            hour = capture_ns // HOUR_NS * HOUR_NS
            ahead = hour + past - capture_ns
            self._hour_ns = hour + (HOUR_NS if ahead < -HALF_HOUR_NS else -HOUR_NS if ahead > HALF_HOUR_NS else 0)
        elif self._hour_ns + past < self._last_ns - HALF_HOUR_NS:
            self._hour_ns += HOUR_NS  # across a top of the hour
        elif self._hour_ns + past > self._last_ns + HALF_HOUR_NS:
            self._hour_ns -= HOUR_NS  # a packet from just before one already counted across
        self._last_ns = self._hour_ns + past
        return self._last_ns


@dataclass(frozen=True)
class Arrival:
    """A GPRMC sentence's first appearance in the position packets: sensor and capture times, and its epoch (UTC), ns."""

    sensor_ns: int
    capture_ns: int
    epoch_ns: int


@dataclass
class ClockSurvey:
    """What a first pass over a capture learns about its clocks; `clocks()` makes the timeline of it."""

    data_offsets: list[int] = field(default_factory=list)  # capture - sensor of every SAMPLE_EVERY-th data packet
    data_packets: int = 0
    first_sensor_ns: int | None = None
    last_sensor_ns: int | None = None
    arrivals: list[Arrival] = field(default_factory=list)  # each new sentence; the first one was maybe already old
    pps: dict[int, int] = field(default_factory=dict)

    def data(self, capture_ns: int, sensor_ns: int) -> None:
        if self.data_packets % SAMPLE_EVERY == 0:
            self.data_offsets.append(capture_ns - sensor_ns)
        self.data_packets += 1
        self.first_sensor_ns = sensor_ns if self.first_sensor_ns is None else min(self.first_sensor_ns, sensor_ns)
        self.last_sensor_ns = sensor_ns if self.last_sensor_ns is None else max(self.last_sensor_ns, sensor_ns)

    def position(self, pps: int) -> None:
        self.pps[pps] = self.pps.get(pps, 0) + 1

    def sentence(self, arrival: Arrival) -> None:
        """A GPRMC that differs from the one before (the first of the capture included)."""
        self.arrivals.append(arrival)

    def gnss_from(self) -> str:
        """What the offsets to GNSS time were measured on."""
        if len(self.arrivals) > 1:
            return f"{len(self.arrivals) - 1} GPRMC arrivals"
        return "the first GPRMC's age at the first position packet (a bound)" if self.arrivals else ""

    def clocks(self, revolution_s: float) -> Clocks:
        """The timeline (module docstring)."""
        capture_minus_sensor = int(np.median(self.data_offsets)) if self.data_offsets else 0
        arrived = self.arrivals[1:] or self.arrivals[:1]  # the first was in the capture from its start: maybe long before
        sensor_minus_gnss = min((a.sensor_ns - a.epoch_ns for a in arrived), default=None)
        capture_minus_gnss = min((a.capture_ns - a.epoch_ns for a in arrived), default=None)
        locked = self.pps.get(PPS_LOCKED, 0) > sum(self.pps.values()) / 2
        if locked:
            timeline, to_utc = "sensor clock (PPS-locked to UTC)", 0
        elif sensor_minus_gnss is not None:
            timeline, to_utc = "GNSS time: the sensor clock minus its offset to the GPRMC epochs", -sensor_minus_gnss
        else:
            timeline, to_utc = "capture clock: the sensor clock plus its median offset to the capture clock", capture_minus_sensor
        late = max((a.sensor_ns + to_utc - a.epoch_ns for a in self.arrivals), default=0)
        return Clocks(
            timeline=timeline,
            sensor_to_utc_ns=to_utc,
            capture_minus_sensor_s=capture_minus_sensor / 1e9 if self.data_offsets else math.nan,
            sensor_minus_gnss_s=sensor_minus_gnss / 1e9 if sensor_minus_gnss is not None else math.nan,
            capture_minus_gnss_s=capture_minus_gnss / 1e9 if capture_minus_gnss is not None else math.nan,
            gnss_from=self.gnss_from(),
            pps=PPS_STATUS.get(max(self.pps, key=lambda status: self.pps[status]), "?") if self.pps else "no position packets",
            lag_ns=max(late, 0) + round(2 * revolution_s * 1e9),
        )


@dataclass(frozen=True)
class Clocks:
    """A capture's timeline: how the sensor's clock maps onto it, the offsets measured between the clocks (s), and how
    long a reader must hold events so that none arrives after a later one was let go."""

    timeline: str
    sensor_to_utc_ns: int
    capture_minus_sensor_s: float
    sensor_minus_gnss_s: float
    capture_minus_gnss_s: float
    gnss_from: str
    pps: str
    lag_ns: int

    def utc_ns(self, sensor_ns: int) -> int:
        """The timeline time of a sensor time."""
        return sensor_ns + self.sensor_to_utc_ns

    def describe(self) -> dict:
        """The timeline and offsets, for metrics.json and the report."""
        return {
            "timeline": self.timeline,
            "capture_minus_sensor_s": self.capture_minus_sensor_s,
            "sensor_minus_gnss_s": self.sensor_minus_gnss_s,
            "capture_minus_gnss_s": self.capture_minus_gnss_s,
            "gnss_offsets_from": self.gnss_from,
            "pps": self.pps,
        }
