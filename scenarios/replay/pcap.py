"""A Velodyne HDL-32E capture (libpcap) read into time-ordered scans and fixes.

Data packets (UDP payloads of 1206 bytes) are decoded by velodyne_decoder with VeloView's HDL-32E
calibration (every beam from the sensor's centre, as the simulator casts them), one scan per
revolution cut where the scenario's lidar starts one ([lidar] start_azimuth_deg, by default
behind the sensor), stamped with the sensor's time of its first packet; the decoder numbers rings
bottom-up, the scan gets them back as laser ids (firing order), as the simulator's. Position
packets (512 bytes) carry the receiver's latest GPRMC: each new sentence is a fix stamped with its
own UTC time (0.01 s), with position, quality and course but no altitude, HDOP or satellites (see
scenarios.replay.fixes: the estimators take it as an open-sky fix of HDOP 1).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import dpkt
import numpy as np
import velodyne_decoder as vd

from scenarios.export import dialect
from scenarios.pipeline.stream import ScanEvent
from scenarios.replay import fixes
from scenarios.replay.recording import REORDER_LAG_S, Event, Geo, Place, RecordedFix, Recording, TimeOrder, unix_ns
from sim import nmea
from sim.scan import POINT_DTYPE, Scan

DATA_BYTES = vd.PACKET_SIZE
POSITION_BYTES = vd.TELEMETRY_PACKET_SIZE


def config(start_azimuth_deg: float) -> vd.Config:
    """velodyne_decoder set for the HDL-32E: VeloView's calibration, scans cut where a revolution starts (clockwise azimuth)."""
    out = vd.Config(model=vd.Model.HDL32E, calibration=vd.get_bundled_calibration("HDL-32E.yml"), timestamp_first_packet=True)
    out.cut_angle = -start_azimuth_deg % 360.0
    return out


def read(path: str | Path, place: Place) -> Recording:
    """Open the capture, check it holds HDL-32E data packets and fix its time base and ENU origin; ValueError (one line) otherwise."""
    path = Path(path)
    first = last = None
    position = None
    packets = 0
    for ts, payload in payloads(path):
        first = ts if first is None else first
        last = ts
        packets += len(payload) == DATA_BYTES
        if position is None and len(payload) == POSITION_BYTES:
            position = rmc_position(payload, place)
    if not packets:
        raise ValueError(f"{path}: no Velodyne data packets (UDP payloads of {DATA_BYTES} bytes)")
    geo = Geo.choose(place, ns_of(first), position)
    return Recording(
        path,
        "pcap",
        f"HDL-32E data packets ({packets})",
        "GPRMC of the position packets",
        geo,
        geo.seconds(ns_of(first)),
        geo.seconds(ns_of(last)),
        events=lambda: events(path, geo, place.start_azimuth_deg),
    )


def payloads(path: Path) -> Iterator[tuple[float, bytes]]:
    """(record time, UDP payload) of every UDP datagram in the capture; a one-line ValueError when it is no libpcap file."""
    if not path.is_file():
        raise ValueError(f"{path}: no such capture")
    with path.open("rb") as handle:
        try:
            reader = dpkt.pcap.Reader(handle)
        except ValueError as exc:
            raise ValueError(f"{path}: not a libpcap capture ({exc})") from None
        for ts, buf in reader:
            try:
                udp = dpkt.ethernet.Ethernet(buf).data.data
            except (dpkt.UnpackError, AttributeError):
                continue
            if isinstance(udp, dpkt.udp.UDP):
                yield ts, bytes(udp.data)


def ns_of(seconds: float) -> int:
    """Integer nanoseconds of a microsecond-resolution time in float seconds."""
    return round(seconds * 1e6) * 1000


def rmc_position(payload: bytes, place: Place) -> tuple[float, float, float] | None:
    """(lat, lon, the origin's altitude) of a position packet's valid GPRMC, else None."""
    fields = rmc(sentence(payload))
    if fields is None or not fields["valid"] or not math.isfinite(fields["lat"]):
        return None
    return fields["lat"], fields["lon"], place.origin[2]


def sentence(payload: bytes) -> str:
    """The NMEA sentence of a position packet ('' when it has none)."""
    return vd.TelemetryPacket(np.frombuffer(payload, np.uint8)).nmea_sentence.strip()


def rmc(line: str) -> dict | None:
    """A position packet's sentence decoded (sim.nmea.parse) if it is an RMC with a good checksum, else None."""
    try:
        fields = nmea.parse(line) if line else None
    except ValueError:
        return None
    return fields if fields is not None and fields["type"] == "RMC" else None


def events(path: Path, geo: Geo, start_azimuth_deg: float) -> Iterator[Event]:
    """Scans and fixes in time order, decoded lazily."""
    decoder, order, latest = vd.StreamDecoder(config(start_azimuth_deg)), TimeOrder(), ""
    for ts, payload in payloads(path):
        if len(payload) == DATA_BYTES:
            decoded = decoder.decode(ts, payload, True)
            if decoded is not None:
                order.add(scan_event(*decoded, geo))
        elif len(payload) == POSITION_BYTES:
            line = sentence(payload)
            fields = rmc(line) if line != latest else None
            latest = line
            if fields is not None:
                stamp = geo.seconds(unix_ns(rmc_utc(fields)))
                order.add(RecordedFix(stamp, fixes.from_nmea(stamp, [latest], geo), (latest,)))
        yield from order.release(geo.seconds(ns_of(ts)) - REORDER_LAG_S)
    decoded = decoder.finish(True)
    if decoded is not None:
        order.add(scan_event(*decoded, geo))
    yield from order.rest()


def rmc_utc(fields: dict) -> datetime:
    """The UTC time of a decoded RMC (its date and time of day)."""
    day = fields["date"]
    return datetime(day.year, day.month, day.day, tzinfo=UTC) + timedelta(seconds=fields["seconds_of_day"])


def scan_event(stamp, points: np.ndarray, geo: Geo) -> ScanEvent:
    """A decoded revolution as a ScanEvent at the sensor's time of its first packet (the host's when the sensor gives none)."""
    seconds = stamp.device if math.isfinite(stamp.device) and stamp.device > 0 else stamp.host
    out = np.zeros(len(points), POINT_DTYPE)
    for name in ("x", "y", "z", "intensity", "time"):
        out[name] = points[name]
    out["ring"] = dialect.laser_of_ring(points["ring"])
    t = geo.seconds(ns_of(seconds))
    return ScanEvent(t, Scan(t, out))
