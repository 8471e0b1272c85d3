"""A rosbag2 bag (sqlite3 or MCAP storage; also a ROS 1 .bag) read with rosbags' AnyReader into time-ordered scans and fixes.

Topics are picked as KISS-ICP's rosbag dataloader picks its cloud: the only
sensor_msgs/msg/PointCloud2 topic, or the one `lidar_topic` names (several and none named: a
one-line error listing them); a bag without any is replayed on its GPS alone (GNSS-only). The GPS:
the only nmea_msgs/msg/Sentence topic (the receiver's own sentences, with its satellites, C/N0 and
dead-reckoning quality), else the only sensor_msgs/msg/NavSatFix topic, or the one `gps_topic`
names (either type). With NMEA, the only NavSatFix topic and the only gps_msgs/msg/GPSFix topic, if
any, refine its epochs (scenarios.replay.fixes), and a riverbench export's riverbench_msgs/msg/GnssReport
gives them its DOPs and satellites unrounded (scenarios.replay.reports). When the scenario feeds an estimator the IMU: the only
sensor_msgs/msg/Imu topic, or the one `imu_topic` names, read in base_link by its /tf_static mount
(scenarios.replay.imu; a bag without an Imu topic replays without it). When it feeds one the compass: the only
geometry_msgs/msg/QuaternionStamped and sensor_msgs/msg/MagneticField topics, an AHRS's orientation and field as
xsens_mti_driver records them (scenarios.replay.compass; without them the replay runs without a compass). Every event
is stamped with its message's header stamp (see scenarios.replay.recording for the time base and the ordering; scenarios.replay.clouds
and .fixes for the fields).
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from rosbags.highlevel import AnyReader

from scenarios.export.ros_messages import GNSS_REPORT, typestore
from scenarios.pipeline.feed import BadScan
from scenarios.pipeline.stream import ScanEvent
from scenarios.replay import clouds, fixes, reports
from scenarios.replay import imu as imu_module
from scenarios.replay.compass import ATTITUDE, MAGNETIC, CompassPairing, CompassTopics
from scenarios.replay.recording import REORDER_LAG_S, Event, Geo, LogStats, Place, RecordedFix, Recording, TimeOrder
from sim.nmea.epochs import Line, Splitter, assemble

CLOUD = "sensor_msgs/msg/PointCloud2"
SENTENCE = "nmea_msgs/msg/Sentence"
NAVSAT = "sensor_msgs/msg/NavSatFix"
GPSFIX = "gps_msgs/msg/GPSFix"
IMU = "sensor_msgs/msg/Imu"
TF_STATIC = "/tf_static"
RATE_PROBE = 50
"""Imu messages whose header stamps give the IMU's rate (the median interval)."""


def read(path: str | Path, place: Place, lidar_topic: str | None = None, gps_topic: str | None = None, imu_topic: str | None = None) -> Recording:
    """Open the bag, pick its topics and fix its time base and ENU origin; ValueError (one line) when it cannot be replayed."""
    path = Path(path)
    with opened(path) as reader:
        types = {topic: info.msgtype for topic, info in reader.topics.items()}
        clouds_in_bag = lidar_topic is not None or CLOUD in types.values()
        lidar = pick(path, types, (CLOUD,), lidar_topic, "--lidar-topic") if clouds_in_bag else ""
        gps = pick(path, types, (SENTENCE,), gps_topic, "--gps-topic", fallback=(NAVSAT,))
        refine = tuple(t for t in (sole(types, NAVSAT), sole(types, GPSFIX), sole(types, GNSS_REPORT)) if t) if types[gps] == SENTENCE else ()
        if lidar and not reader.topics[lidar].msgcount:
            raise ValueError(f"{path}: topic {lidar} holds no point cloud")
        if not lidar and not reader.topics[gps].msgcount:
            raise ValueError(f"{path}: no PointCloud2 topic, and the GPS topic {gps} holds no message")
        geo = Geo.choose(place, reader.start_time, first_position(reader, gps, place))
        span = (geo.seconds(reader.start_time), geo.seconds(reader.end_time))
        kind = "rosbag2" if reader.is2 else "ROS 1 bag"
        imu = imu_mount(reader, path, types, place, imu_topic)
        compass = compass_topics(types, place)
    source = gps + (f" (positions, DOPs and satellites refined by {' and '.join(refine)})" if refine else "")
    stats = LogStats() if types[gps] == SENTENCE else None
    return Recording(
        path,
        kind,
        lidar,
        source,
        geo,
        *span,
        events=lambda: imu_module.batched(events(path, lidar, gps, refine, geo, stats, imu, compass)),
        nmea=stats,
        imu_source=imu[1].source if imu else "",
        compass_source=compass.source if compass else "",
    )


def compass_topics(types: dict[str, str], place: Place) -> CompassTopics | None:
    """The bag's AHRS orientation and field topics when the scenario feeds the compass and the bag has one of each."""
    if place.compass_sigma is None:
        return None
    attitude, field = sole(types, ATTITUDE), sole(types, MAGNETIC)
    return CompassTopics(attitude, field, place.compass_sigma) if attitude and field else None


def imu_mount(reader: AnyReader, path: Path, types: dict[str, str], place: Place, named: str | None) -> tuple[str, imu_module.ImuMount] | None:
    """(topic, mount) of the bag's IMU when the scenario feeds one (or `named` asks for it) and the bag has one; else None."""
    if named is None and (place.imu_noise is None or IMU not in types.values()):
        return None
    topic = pick(path, types, (IMU,), named, "--imu-topic")
    connections = [c for c in reader.connections if c.topic == topic]
    first, stamps = None, []
    for connection, _, raw in reader.messages(connections=connections):
        msg = reader.deserialize(raw, connection.msgtype)
        first = first or msg
        stamps.append(header_ns(msg))
        if len(stamps) > RATE_PROBE:
            break
    if first is None:
        raise ValueError(f"{path}: topic {topic} holds no Imu message")
    steps = [b - a for a, b in zip(stamps, stamps[1:]) if b > a]
    rate_hz = 1e9 / statistics.median(steps) if steps else math.nan
    static = [c for c in reader.connections if c.topic == TF_STATIC]
    tf = imu_module.transforms(reader.deserialize(raw, c.msgtype) for c, _, raw in reader.messages(connections=static)) if static else None
    noise = place.imu_noise if place.imu_noise is not None else (math.nan, math.nan)
    return topic, imu_module.mount(path, topic, first.header.frame_id, tf, noise, rate_hz)


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


def sole(types: dict[str, str], kind: str) -> str | None:
    """The bag's only topic of message type `kind` (None when it has none or several)."""
    found = [t for t, k in types.items() if k == kind]
    return found[0] if len(found) == 1 else None


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


def events(
    path: Path,
    lidar: str,
    gps: str,
    refine: tuple[str, ...],
    geo: Geo,
    stats: LogStats | None,
    imu: tuple[str, imu_module.ImuMount] | None = None,
    compass: CompassTopics | None = None,
) -> Iterator[Event | imu_module.ImuReading]:
    """Scans, fixes, unreadable scans, IMU readings and compass headings in time order, read lazily (NMEA lines and epochs
    counted into `stats`)."""
    order = TimeOrder()
    pairing = CompassPairing(compass.sigma if compass else math.nan)
    precise: dict[int, dict[str, object]] = {}  # header stamp -> message type -> the refining message
    epochs = Splitter(stats.tally if stats is not None else None)
    with opened(path) as reader:
        imu_topic = imu[0] if imu else ""
        compass_topics = (compass.attitude, compass.field) if compass else ()
        connections = [c for c in reader.connections if c.topic in (lidar, gps, imu_topic, *compass_topics, *refine)]
        for connection, log_ns, raw in reader.messages(connections=connections):
            if lidar and connection.topic == lidar:
                order.add(scan_event(reader, connection.msgtype, raw, lidar, geo.seconds(log_ns), geo))
                continue
            msg = reader.deserialize(raw, connection.msgtype)
            if imu and connection.topic == imu_topic:
                order.add(imu_module.reading(msg, geo.seconds(header_ns(msg)), imu[1]))
            elif connection.topic in compass_topics:
                ns = header_ns(msg)
                take = pairing.attitude if connection.msgtype == ATTITUDE else pairing.field
                if (heading := take(ns, geo.seconds(ns), msg)) is not None:
                    order.add(heading)
            elif connection.topic in refine:
                precise.setdefault(header_ns(msg), {})[connection.msgtype] = msg
            elif connection.msgtype == SENTENCE:
                add_epoch(order, epochs.add(header_ns(msg), msg.sentence), precise, geo, stats)
            else:
                stamp = geo.seconds(header_ns(msg))
                order.add(RecordedFix(stamp, fixes.from_navsatfix(stamp, msg, geo)))
            pending = math.inf if epochs.open_tag is None else geo.seconds(epochs.open_tag)
            yield from order.release(min(geo.seconds(log_ns) - REORDER_LAG_S, pending))
        add_epoch(order, epochs.close(), precise, geo, stats)
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


def add_epoch(order: TimeOrder, closed: list[Line] | None, precise: dict[int, dict[str, object]], geo: Geo, stats: LogStats | None) -> None:
    """Queue a closed NMEA epoch's fix (stamped with its first sentence's header), refined by the NavSatFix, GPSFix and
    GnssReport stamped like one of its sentences (older ones dropped)."""
    if closed is None:
        return
    stamps, lines = [line.tag for line in closed], [line.text for line in closed]
    stamp = geo.seconds(stamps[0])
    epoch = assemble(closed)
    fix = fixes.from_epoch(stamp, epoch, geo)
    if stats is not None:
        stats.epochs += 1
        stats.with_fix += epoch.has_fix
    match = next((precise[ns] for ns in stamps if ns in precise), {})
    for ns in [ns for ns in precise if ns <= stamps[-1]]:
        del precise[ns]
    if fix is not None:
        fix = fixes.refined(fix, match.get(NAVSAT), match.get(GPSFIX), geo)
        report = match.get(GNSS_REPORT)
        order.add(RecordedFix(stamp, fix if report is None else reports.applied(fix, report, geo), tuple(lines)))
