"""A rosbag2 bag (sqlite3 or MCAP storage; also a ROS 1 .bag) read with rosbags' AnyReader into time-ordered scans and fixes.

Topics are picked as KISS-ICP's rosbag dataloader picks its cloud: the only
sensor_msgs/msg/PointCloud2 topic, or the one `lidar_topic` names (several and none named: a
one-line error listing them). The GPS: the only nmea_msgs/msg/Sentence topic (the receiver's own
sentences, with its satellites, C/N0 and dead-reckoning quality), else the only
sensor_msgs/msg/NavSatFix topic, or the one `gps_topic` names (either type). A riverbench export's
riverbench_msgs/msg/GnssReport topic, when the bag has one, gives each fix stamped like it its DOPs
and satellites unrounded (scenarios.replay.reports). Every event is stamped with its message's
header stamp (see scenarios.replay.recording for the time base and the ordering;
scenarios.replay.clouds and .fixes for the fields).
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from rosbags.highlevel import AnyReader

from scenarios.export.ros_messages import GNSS_REPORT, typestore
from scenarios.pipeline.feed import BadScan
from scenarios.pipeline.stream import ScanEvent
from scenarios.replay import clouds, fixes, reports
from scenarios.replay.recording import REORDER_LAG_S, Event, Geo, Place, RecordedFix, Recording, TimeOrder

CLOUD = "sensor_msgs/msg/PointCloud2"
SENTENCE = "nmea_msgs/msg/Sentence"
NAVSAT = "sensor_msgs/msg/NavSatFix"


def read(path: str | Path, place: Place, lidar_topic: str | None = None, gps_topic: str | None = None) -> Recording:
    """Open the bag, pick its topics and fix its time base and ENU origin; ValueError (one line) when it cannot be replayed."""
    path = Path(path)
    with opened(path) as reader:
        types = {topic: info.msgtype for topic, info in reader.topics.items()}
        lidar = pick(path, types, (CLOUD,), lidar_topic, "--lidar-topic")
        gps = pick(path, types, (SENTENCE,), gps_topic, "--gps-topic", fallback=(NAVSAT,))
        navsat = [t for t, kind in types.items() if kind == NAVSAT]
        refine = navsat[0] if types[gps] == SENTENCE and len(navsat) == 1 else None
        found = [t for t, kind in types.items() if kind == GNSS_REPORT]
        report = found[0] if len(found) == 1 else None
        if not reader.topics[lidar].msgcount:
            raise ValueError(f"{path}: topic {lidar} holds no point cloud")
        geo = Geo.choose(place, reader.start_time, first_position(reader, gps, place))
        span = (geo.seconds(reader.start_time), geo.seconds(reader.end_time))
        kind = "rosbag2" if reader.is2 else "ROS 1 bag"
    source = gps + (f" (positions and DOPs refined by {refine})" if refine else "") + (f" (DOPs and satellites from {report})" if report else "")
    return Recording(path, kind, lidar, source, geo, *span, events=lambda: events(path, lidar, gps, refine, report, geo))


@contextmanager
def opened(path: Path) -> Iterator[AnyReader]:
    """An open AnyReader on the bag (with nmea_msgs/Sentence known), closed after; a one-line ValueError when it cannot open."""
    if not path.exists():
        raise ValueError(f"{path}: no such bag")
    try:
        reader = AnyReader([path], default_typestore=typestore())
        reader.open()
    except Exception as exc:  # rosbags raises its own error types for every kind of unreadable bag
        raise ValueError(f"{path}: not a readable bag: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}") from None
    try:
        yield reader
    finally:
        reader.close()


def pick(path: Path, types: dict[str, str], wanted: tuple[str, ...], named: str | None, option: str, fallback: tuple[str, ...] = ()) -> str:
    """The topic `named`, else the only topic of a wanted type (else of a fallback type); a one-line ValueError otherwise."""
    kinds = wanted + fallback
    listed = ", ".join(f"{t} ({types[t].rsplit('/', 1)[-1]})" for t in sorted(types) if types[t] in kinds) or "none"
    if named is not None:
        if types.get(named) not in kinds:
            raise ValueError(f"{path}: no {' or '.join(k.rsplit('/', 1)[-1] for k in kinds)} topic {named!r}; the bag's: {listed}")
        return named
    for group in (wanted, fallback):
        found = sorted(t for t, kind in types.items() if kind in group)
        if len(found) == 1:
            return found[0]
        if len(found) > 1:
            raise ValueError(
                f"{path}: {len(found)} {' or '.join(k.rsplit('/', 1)[-1] for k in group)} topics ({', '.join(found)}): pick one with {option}"
            )
    raise ValueError(f"{path}: no {' or '.join(k.rsplit('/', 1)[-1] for k in kinds)} topic")


def first_position(reader: AnyReader, gps: str, place: Place) -> tuple[float, float, float] | None:
    """(lat, lon, alt) of the first message on the GPS topic with a position (None if there is none)."""
    probe = Geo.choose(place, 0, None)
    connections = [c for c in reader.connections if c.topic == gps]
    for connection, _, raw in reader.messages(connections=connections):
        msg = reader.deserialize(raw, connection.msgtype)
        fix = fixes.from_nmea(0.0, [msg.sentence], probe) if connection.msgtype == SENTENCE else fixes.from_navsatfix(0.0, msg, probe)
        if fix is not None and fix.quality:
            return fix.lat, fix.lon, fix.alt
    return None


def header_ns(msg) -> int:
    """A message's header stamp in integer nanoseconds."""
    return msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec


def events(path: Path, lidar: str, gps: str, refine: str | None, report: str | None, geo: Geo) -> Iterator[Event]:
    """Scans, fixes and unreadable scans in time order, read lazily."""
    order, epochs, precise, reported = TimeOrder(), fixes.Epochs(), {}, {}
    with opened(path) as reader:
        connections = [c for c in reader.connections if c.topic in (lidar, gps, refine, report)]
        held: list = []  # NavSatFix-only fixes wait for a report stamped like them (logged at the same time)
        for connection, log_ns, raw in reader.messages(connections=connections):
            if connection.topic == lidar:
                order.add(scan_event(reader, connection.msgtype, raw, lidar, geo.seconds(log_ns), geo))
                continue
            msg = reader.deserialize(raw, connection.msgtype)
            if connection.topic == refine:
                precise[header_ns(msg)] = msg
            elif connection.topic == report:
                reported[header_ns(msg)] = msg
            elif connection.msgtype == SENTENCE:
                add_epoch(order, epochs.add(header_ns(msg), msg.sentence), precise, reported, geo)
            else:
                held.append(msg)
            held = add_navsat(order, held, log_ns, reported, geo)
            pending = math.inf if epochs.open_ns is None else geo.seconds(epochs.open_ns)
            yield from order.release(min(geo.seconds(log_ns) - REORDER_LAG_S, pending))
        add_navsat(order, held, None, reported, geo)
        add_epoch(order, epochs.close(), precise, reported, geo)
        yield from order.rest()


def scan_event(reader: AnyReader, msgtype: str, raw: bytes, topic: str, logged: float, geo: Geo) -> ScanEvent | BadScan:
    """One cloud message as a ScanEvent, or a BadScan saying why it cannot be one (stamped when it was logged if undecodable)."""
    try:
        msg = reader.deserialize(raw, msgtype)
    except Exception as exc:  # a corrupt message: rosbags' CDR decoder raises several error types
        return BadScan(logged, topic, f"undecodable PointCloud2: {type(exc).__name__}: {exc}")
    ns = header_ns(msg)
    stamp = geo.seconds(ns)
    try:
        return ScanEvent(stamp, clouds.scan(msg, stamp, ns / 1e9))
    except ValueError as exc:
        return BadScan(stamp, topic, str(exc))


def add_navsat(order: TimeOrder, held: list, log_ns: int | None, reported: dict[int, object], geo: Geo) -> list:
    """Queue the held NavSatFix fixes logged before `log_ns` (all when None), each with its report if there is one; the rest stay held."""
    keep = []
    for msg in held:
        ns = header_ns(msg)
        if log_ns is not None and ns >= log_ns:
            keep.append(msg)
            continue
        stamp = geo.seconds(ns)
        fix = fixes.from_navsatfix(stamp, msg, geo)
        order.add(RecordedFix(stamp, reports.applied(fix, reported.pop(ns), geo) if ns in reported else fix))
    return keep


def add_epoch(order: TimeOrder, epoch: tuple[list[int], list[str]] | None, precise: dict[int, object], reported: dict[int, object], geo: Geo) -> None:
    """Queue a closed NMEA epoch's fix, refined by the NavSatFix and the report stamped like one of its sentences (older ones dropped)."""
    if epoch is None:
        return
    stamps, lines = epoch
    stamp = geo.seconds(stamps[0])
    fix = fixes.from_nmea(stamp, lines, geo)
    match = next((precise[ns] for ns in stamps if ns in precise), None)
    report = next((reported[ns] for ns in stamps if ns in reported), None)
    for table in (precise, reported):
        for ns in [ns for ns in table if ns <= stamps[-1]]:
            del table[ns]
    if fix is not None:
        fix = fix if match is None else fixes.refined(fix, match, geo)
        order.add(RecordedFix(stamp, fix if report is None else reports.applied(fix, report, geo), tuple(lines)))
