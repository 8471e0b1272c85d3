"""A rosbag2 bag directory (sqlite3 or MCAP storage), written with rosbags, as ROS 2 drivers would record it.

    <out>/metadata.yaml                 rosbag2 metadata, version 8 (Iron's; QoS profiles as YAML strings, as Humble writes them)
    <out>/<scenario>_0.db3 | .mcap      the messages, named as `ros2 bag record` names a bag's first file

Topics, named as the ROS drivers publish them (messages detailed in ros_messages.py):
    /velodyne_points     sensor_msgs/PointCloud2, one per revolution (velodyne_pointcloud's transform node)
    /gps/fix             sensor_msgs/NavSatFix, one per fix (nmea_navsat_driver, ublox, septentrio drivers)
    /nmea_sentence       nmea_msgs/Sentence, each NMEA sentence of each fix (nmea_navsat_driver)
    /gps/report          riverbench_msgs/GnssReport, each fix's DOPs and satellites (C/N0, elevation) unrounded
    /tf_static           tf2_msgs/TFMessage, once at the stream's start: base_link -> velodyne (the lidar mount)
                         and base_link -> gps (the antenna offset); offered QoS transient_local (latched)
    /tf                  tf2_msgs/TFMessage, map -> base_link ground truth at each scan's stamp
    /odom/ground_truth   nav_msgs/Odometry, the same pose
Every message is recorded at its header stamp, the simulation stamp rounded to the nanosecond, except
that a fix the run took before a scan whose stamp rounds to the same nanosecond (a fix at 0.6 s and a
scan at 0.6000000000000001 s: both sensors' epochs, on grids that meet, differ in the last bit of a
float) is stamped 1 ns earlier: a reader orders a scan before a fix at the same stamp, as the
simulation does at equal stamps, so the bag keeps the run's order and a replay feeds the estimators
what the run fed them. The bag is written frame by frame: each frame's cloud and true pose are on disk
before the next frame is read (the sqlite3 transaction is committed, the MCAP chunk closed: a chunk per
revolution, the last revolution's fixes in one more), its fixes go with the next frame, once the next
scan's stamp is known (for that rule), so memory stays flat. Read with rosbags' AnyReader, `ros2 bag`,
or `kiss_icp_pipeline <out>`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from itertools import chain
from pathlib import Path

import numpy as np
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys.store import Typestore

from scenarios.export import ros_messages as msgs
from scenarios.export.frames import Frame, StreamInfo

INFINITE = QosTime(9223372036, 854775807)  # RMW_DURATION_INFINITE, as Humble and later record it


def offered(durability: QosDurability) -> list[Qos]:
    """The offered QoS profile `ros2 bag record` stores for a reliable publisher of this durability."""
    return [Qos(QosHistory.UNKNOWN, 0, QosReliability.RELIABLE, durability, INFINITE, INFINITE, QosLiveliness.AUTOMATIC, INFINITE, False)]


TOPICS = {
    "/velodyne_points": ("sensor_msgs/msg/PointCloud2", offered(QosDurability.VOLATILE)),
    "/gps/fix": ("sensor_msgs/msg/NavSatFix", offered(QosDurability.VOLATILE)),
    "/nmea_sentence": ("nmea_msgs/msg/Sentence", offered(QosDurability.VOLATILE)),
    "/gps/report": (msgs.GNSS_REPORT, offered(QosDurability.VOLATILE)),
    "/tf_static": ("tf2_msgs/msg/TFMessage", offered(QosDurability.TRANSIENT_LOCAL)),
    "/tf": ("tf2_msgs/msg/TFMessage", offered(QosDurability.VOLATILE)),
    "/odom/ground_truth": ("nav_msgs/msg/Odometry", offered(QosDurability.VOLATILE)),
}


def write_sqlite3(info: StreamInfo, frames: Iterable[Frame], out: Path) -> dict[str, int]:
    """Write the frames as a rosbag2 bag with sqlite3 storage into the empty directory `out`."""
    return write(info, frames, out, StoragePlugin.SQLITE3)


def write_mcap(info: StreamInfo, frames: Iterable[Frame], out: Path) -> dict[str, int]:
    """Write the frames as a rosbag2 bag with MCAP storage into the empty directory `out`."""
    return write(info, frames, out, StoragePlugin.MCAP)


def write(info: StreamInfo, frames: Iterable[Frame], out: Path, storage: StoragePlugin) -> dict[str, int]:
    """Stream the frames into a bag at `out` (rosbags creates the bag directory itself, so it writes a
    subdirectory and its two files move up into `out` once closed); returns the counts written."""
    store = msgs.typestore()
    bag = out / f"{info.scenario}_0"
    counts = {"messages": 0, "points": 0, "fixes": 0}
    with Writer(bag, version=8, storage_plugin=storage) as writer:
        flush = streaming(writer, storage)
        connections = {
            topic: writer.add_connection(topic, msgtype, typestore=store, offered_qos_profiles=qos) for topic, (msgtype, qos) in TOPICS.items()
        }
        for batch in chain([static_messages(store, info)], frame_batches(store, info, frames)):
            for topic, ns, msg in batch:
                writer.write(connections[topic], ns, store.serialize_cdr(msg, msg.__msgtype__))
                counts["messages"] += 1
                counts["points"] += msg.width if topic == "/velodyne_points" else 0
                counts["fixes"] += topic == "/gps/fix"
            flush()
    for path in bag.iterdir():
        path.rename(out / path.name)
    bag.rmdir()
    return counts


def static_messages(store: Typestore, info: StreamInfo) -> list[tuple[str, int, object]]:
    """/tf_static at the stream's start: base_link -> velodyne (the mount) and base_link -> gps (the antenna offset)."""
    ns = msgs.ros_ns(info.epoch_utc, info.t_start)
    antenna = np.eye(4)
    antenna[:3, 3] = info.antenna_offset_m
    return [
        (
            "/tf_static",
            ns,
            msgs.tf_message(
                store,
                [
                    msgs.transform(store, ns, msgs.BASE_FRAME, msgs.LIDAR_FRAME, info.mount),
                    msgs.transform(store, ns, msgs.BASE_FRAME, msgs.GPS_FRAME, antenna),
                ],
            ),
        )
    ]


def frame_batches(store: Typestore, info: StreamInfo, frames: Iterable[Frame]) -> Iterator[list[tuple[str, int, object]]]:
    """The messages to write (and flush) as each frame comes: the previous frame's fixes, stamped now that the next scan's
    stamp is known (see fix_ns), then this frame's scan; the last frame's fixes at the end."""
    previous: Frame | None = None
    for frame in frames:
        yield (fix_messages(store, info, previous, frame.stamp) if previous is not None else []) + scan_messages(store, info, frame)
        previous = frame
    if previous is not None and previous.fixes:
        yield fix_messages(store, info, previous, None)


def fix_ns(info: StreamInfo, stamp: float, next_scan: float | None) -> int:
    """A fix's ROS time: its stamp's, or 1 ns before the next scan's when it came before that scan but rounds to its stamp."""
    ns = msgs.ros_ns(info.epoch_utc, stamp)
    if next_scan is not None and stamp < next_scan and ns >= (scan_ns := msgs.ros_ns(info.epoch_utc, next_scan)):
        return scan_ns - 1
    return ns


def scan_messages(store: Typestore, info: StreamInfo, frame: Frame) -> list[tuple[str, int, object]]:
    """The frame's cloud and true pose at the scan's stamp."""
    ns = msgs.ros_ns(info.epoch_utc, frame.stamp)
    return [
        ("/velodyne_points", ns, msgs.point_cloud(store, ns, frame.scan)),
        ("/tf", ns, msgs.tf_message(store, [msgs.transform(store, ns, msgs.MAP_FRAME, msgs.BASE_FRAME, frame.base_pose)])),
        ("/odom/ground_truth", ns, msgs.odometry(store, ns, frame.base_pose)),
    ]


def fix_messages(store: Typestore, info: StreamInfo, frame: Frame, next_scan: float | None) -> list[tuple[str, int, object]]:
    """Each of the frame's fixes, its sentences and its report, at the fix's stamp (kept before the next scan at `next_scan`)."""
    out = []
    for fix in frame.fixes:
        t = fix_ns(info, fix.stamp, next_scan)
        out += [
            ("/gps/fix", t, msgs.nav_sat_fix(store, t, fix)),
            *(("/nmea_sentence", t, s) for s in msgs.sentences(store, t, fix)),
            ("/gps/report", t, msgs.gnss_report(store, t, fix)),
        ]
    return out


def streaming(writer: Writer, storage: StoragePlugin) -> Callable[[], None]:
    """The open writer's flush, which puts everything written so far on disk: commit rosbags' sqlite3 transaction
    (it would hold all until closing; set up first with rosbag2's default "optimized" write pragmas, journal in
    memory and no fsync: the export is all or nothing anyway) or close its MCAP chunk (it would buffer 1 MiB).
    rosbags has no public flush; this reaches its storage object (as rosbags 0.10.9 to 0.11.9 have it)."""
    if storage is StoragePlugin.SQLITE3:
        writer.storage.conn.executescript("PRAGMA journal_mode=MEMORY; PRAGMA synchronous=OFF;")
        return writer.storage.conn.commit
    return writer.storage.close_chunk
