"""A rosbag2 bag directory (sqlite3 or MCAP storage), written with rosbags, as ROS 2 drivers would record it.

    <out>/metadata.yaml                 rosbag2 metadata, version 8 (Iron's; QoS profiles as YAML strings, as Humble writes them)
    <out>/<scenario>_0.db3 | .mcap      the messages, named as `ros2 bag record` names a bag's first file

Topics (messages detailed in ros_messages.py, the drivers' conventions in dialect.py):
    /velodyne_points        sensor_msgs/PointCloud2, one per revolution, frame velodyne (velodyne_pointcloud's transform node)
    /gps/fix                sensor_msgs/NavSatFix, one per fix, frame gps (nmea_navsat_driver; the topic
                            robot_localization's navsat_transform_node subscribes to)
    /nmea_sentence          nmea_msgs/Sentence, each NMEA sentence of each fix (nmea_navsat_driver's nmea_topic_driver input)
    /gps/extended_fix       gps_msgs/GPSFix, one per fix, frame gps (gpsd_client): the DOPs and satellites NavSatFix lacks
    /gps/report             riverbench_msgs/GnssReport, one per fix, frame gps (riverbench's own): its DOPs and satellites
                            unrounded (GPSFix and NMEA give C/N0 and elevation in whole dB-Hz and degrees)
    /tf_static              tf2_msgs/TFMessage, once at the stream's start: the boat's sensor mounts, base_link -> velodyne
                            (the lidar mount) and base_link -> gps (the antenna offset); offered QoS transient_local (latched)
    /imu/data               sensor_msgs/Imu, one per IMU sample, frame imu_link (xsens_mti_driver's topic and frame), only when an
                            estimator is fed the IMU (the scenario simulates one); its mount base_link -> imu_link on /tf_static
    /imu/mag                sensor_msgs/MagneticField, one per compass output, frame imu_link (xsens_mti_driver), tesla; only when
                            an estimator is fed the compass
    /filter/quaternion      geometry_msgs/QuaternionStamped, one per compass output, frame imu_link (xsens_mti_driver's filter
                            orientation, ENU): the unit's heading with the roll and pitch it levelled the field with
    /ground_truth/odom      nav_msgs/Odometry map -> base_link, the true pose at each scan's stamp, covariance zero (exact)
    /ground_truth/tf        tf2_msgs/TFMessage map -> base_link, the same pose, for viewers only: Foxglove takes transforms
                            from every TFMessage topic, ROS tf2 listens on /tf and /tf_static only
    /riverbench/<id>/odom   nav_msgs/Odometry map -> base_link, estimator <id>'s pose at each scan once it is initialised,
                            with its covariance (x, y, yaw; the rest zero: not estimated)
Nothing is published on /tf: a localization stack run on the bag publishes map -> odom -> base_link
there itself (REP-105), and a second parent of base_link would break its tree.
Every message is recorded at its header stamp, the simulation stamp rounded to the nanosecond, except
that a fix the run took before a scan whose stamp rounds to the same nanosecond (a fix at 0.6 s and a
scan at 0.6000000000000001 s: both sensors' epochs, on grids that meet, differ in the last bit of a
float) is stamped 1 ns earlier: a reader orders a scan before a fix at the same stamp, as the
simulation does at equal stamps, so the bag keeps the run's order and a replay feeds the estimators
what the run fed them. The bag is written frame by frame: each frame's cloud, truth and estimates are
on disk before the next frame is read (the sqlite3 transaction is committed, the MCAP chunk closed: a
chunk per revolution, the last revolution's fixes in one more); its fixes and IMU samples go with the
next frame, once the next scan's stamp is known (for that rule), so memory stays flat. Read with rosbags' AnyReader, `ros2 bag`,
`kiss_icp_pipeline <out>`, evo (`evo_traj bag2 <out> /ground_truth/odom /riverbench/ekf/odom`), or
Foxglove with docs/foxglove/riverbench_layout.json.

A new sensor adds its topic to `topics`, its messages to `scan_messages` or `between_scans` and its mount to `mounts`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from itertools import chain
from pathlib import Path

import numpy as np
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability, QosTime
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys.store import Typestore

from scenarios.export import ros_messages as msgs
from scenarios.export.frames import Frame, StreamInfo

INFINITE = QosTime(9223372036, 854775807)  # RMW_DURATION_INFINITE, as Humble and later record it
CLOUD_TOPIC = "/velodyne_points"
FIX_TOPIC = "/gps/fix"
NMEA_TOPIC = "/nmea_sentence"
EXTENDED_FIX_TOPIC = "/gps/extended_fix"
REPORT_TOPIC = "/gps/report"
STATIC_TF_TOPIC = "/tf_static"
TRUTH_TOPIC = "/ground_truth/odom"
TRUTH_TF_TOPIC = "/ground_truth/tf"
IMU_TOPIC = "/imu/data"
MAG_TOPIC = "/imu/mag"
ATTITUDE_TOPIC = "/filter/quaternion"


def offered(durability: QosDurability) -> list[Qos]:
    """The offered QoS profile `ros2 bag record` stores for a reliable publisher of this durability."""
    return [Qos(QosHistory.UNKNOWN, 0, QosReliability.RELIABLE, durability, INFINITE, INFINITE, QosLiveliness.AUTOMATIC, INFINITE, False)]


@dataclass(frozen=True)
class Topic:
    """A topic of the bag: its name, message type and the QoS its publisher offers."""

    name: str
    msgtype: str
    qos: list[Qos]


def estimate_topic(estimator_id: str) -> str:
    """The Odometry topic of an estimator's output (estimator ids are valid ROS name tokens: scenarios.spec ID_PATTERN)."""
    return f"/riverbench/{estimator_id}/odom"


def topics(info: StreamInfo) -> list[Topic]:
    """Every topic of the stream's bag, the estimators' last."""
    volatile = offered(QosDurability.VOLATILE)
    return [
        Topic(CLOUD_TOPIC, "sensor_msgs/msg/PointCloud2", volatile),
        Topic(FIX_TOPIC, "sensor_msgs/msg/NavSatFix", volatile),
        Topic(NMEA_TOPIC, "nmea_msgs/msg/Sentence", volatile),
        Topic(EXTENDED_FIX_TOPIC, "gps_msgs/msg/GPSFix", volatile),
        Topic(REPORT_TOPIC, msgs.GNSS_REPORT, volatile),
        Topic(STATIC_TF_TOPIC, "tf2_msgs/msg/TFMessage", offered(QosDurability.TRANSIENT_LOCAL)),
        Topic(TRUTH_TOPIC, "nav_msgs/msg/Odometry", volatile),
        Topic(TRUTH_TF_TOPIC, "tf2_msgs/msg/TFMessage", volatile),
        *inertial_topics(info),
        *(Topic(estimate_topic(eid), "nav_msgs/msg/Odometry", volatile) for eid in info.estimators),
    ]


def inertial_topics(info: StreamInfo) -> list[Topic]:
    """The IMU's and the compass's topics, when the stream has them."""
    volatile = offered(QosDurability.VOLATILE)
    if info.inertial is None:
        return []
    mag = (
        [Topic(MAG_TOPIC, "sensor_msgs/msg/MagneticField", volatile), Topic(ATTITUDE_TOPIC, "geometry_msgs/msg/QuaternionStamped", volatile)]
        if info.inertial.compass_noise_ut is not None
        else []
    )
    return [Topic(IMU_TOPIC, "sensor_msgs/msg/Imu", volatile), *mag]


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
        connections = {t.name: writer.add_connection(t.name, t.msgtype, typestore=store, offered_qos_profiles=t.qos) for t in topics(info)}
        for batch in chain([static_messages(store, info)], frame_batches(store, info, frames)):
            for topic, ns, msg in batch:
                writer.write(connections[topic], ns, store.serialize_cdr(msg, msg.__msgtype__))
                counts["messages"] += 1
                counts["points"] += msg.width if topic == CLOUD_TOPIC else 0
                counts["fixes"] += topic == FIX_TOPIC
            flush()
    for path in bag.iterdir():
        path.rename(out / path.name)
    bag.rmdir()
    return counts


def mounts(info: StreamInfo) -> list[tuple[str, np.ndarray]]:
    """The boat's fixed sensor frames, (child frame, 4x4 pose base_link<-child): the lidar mount, the antenna offset and,
    with an IMU, its position (axes base_link's, sim.imu)."""
    antenna = np.eye(4)
    antenna[:3, 3] = info.antenna_offset_m
    out = [(msgs.LIDAR_FRAME, info.mount), (msgs.GPS_FRAME, antenna)]
    if info.inertial is not None:
        imu = np.eye(4)
        imu[:3, 3] = info.inertial.lever_m
        out.append((msgs.IMU_FRAME, imu))
    return out


def static_messages(store: Typestore, info: StreamInfo) -> list[tuple[str, int, object]]:
    """/tf_static at the stream's start: base_link -> each mount."""
    ns = msgs.ros_ns(info.epoch_utc, info.t_start)
    transforms = [msgs.transform(store, ns, msgs.BASE_FRAME, child, pose) for child, pose in mounts(info)]
    return [(STATIC_TF_TOPIC, ns, msgs.tf_message(store, transforms))]


def frame_batches(store: Typestore, info: StreamInfo, frames: Iterable[Frame]) -> Iterator[list[tuple[str, int, object]]]:
    """The messages to write (and flush) as each frame comes, in time order: the previous frame's fixes and IMU samples,
    stamped now that this scan's stamp is known (see fix_ns), then this frame's scan messages; the last frame's at the end."""
    previous: Frame | None = None
    for frame in frames:
        yield (between_scans(store, info, previous, frame.stamp) if previous is not None else []) + scan_messages(store, info, frame)
        previous = frame
    if previous is not None and (rest := between_scans(store, info, previous, None)):
        yield rest


def scan_messages(store: Typestore, info: StreamInfo, frame: Frame) -> list[tuple[str, int, object]]:
    """The frame's cloud, true pose and estimates at the scan's stamp."""
    ns = msgs.ros_ns(info.epoch_utc, frame.stamp)
    truth = msgs.transform(store, ns, msgs.MAP_FRAME, msgs.BASE_FRAME, frame.base_pose)
    return [
        (CLOUD_TOPIC, ns, msgs.point_cloud(store, ns, frame.scan)),
        (TRUTH_TOPIC, ns, msgs.odometry(store, ns, frame.base_pose, msgs.BASE_FRAME)),
        (TRUTH_TF_TOPIC, ns, msgs.tf_message(store, [truth])),
        *((estimate_topic(eid), ns, msgs.odometry(store, ns, e.pose, msgs.BASE_FRAME, e.cov)) for eid, e in frame.estimates.items()),
    ]


def between_scans(store: Typestore, info: StreamInfo, frame: Frame, next_scan: float | None) -> list[tuple[str, int, object]]:
    """The frame's fixes (NavSatFix, GPSFix, sentences, report) and IMU samples in time order, up to the next scan at `next_scan`."""
    gnss = []
    for fix in frame.fixes:
        t = fix_ns(info, fix.stamp, next_scan)
        gnss += [
            (FIX_TOPIC, t, msgs.nav_sat_fix(store, t, fix)),
            (EXTENDED_FIX_TOPIC, t, msgs.gps_fix(store, t, fix)),
            *((NMEA_TOPIC, t, s) for s in msgs.sentences(store, t, fix)),
            (REPORT_TOPIC, t, msgs.gnss_report(store, t, fix)),
        ]
    return sorted(gnss + inertial_messages(store, info, frame), key=lambda message: message[1])


def fix_ns(info: StreamInfo, stamp: float, next_scan: float | None) -> int:
    """A fix's ROS time: its stamp's, or 1 ns before the next scan's when it came before that scan but rounds to its stamp."""
    ns = msgs.ros_ns(info.epoch_utc, stamp)
    if next_scan is not None and stamp < next_scan and ns >= (scan_ns := msgs.ros_ns(info.epoch_utc, next_scan)):
        return scan_ns - 1
    return ns


def inertial_messages(store: Typestore, info: StreamInfo, frame: Frame) -> list[tuple[str, int, object]]:
    """The frame's IMU samples on /imu/data and compass outputs on /imu/mag, each at its stamp."""
    if info.inertial is None:
        return []
    rate = info.inertial.rate_hz
    gyro_var, accel_var = info.inertial.gyro_noise**2 * rate, info.inertial.accel_noise**2 * rate
    out = []
    for batch in frame.imu:
        for stamp, gyro, accel in zip(batch.stamp, batch.gyro, batch.accel):
            t = msgs.ros_ns(info.epoch_utc, float(stamp))
            out.append((IMU_TOPIC, t, msgs.imu(store, t, gyro, accel, gyro_var, accel_var)))
    if info.inertial.compass_noise_ut is not None:
        variance = (info.inertial.compass_noise_ut * 1e-6) ** 2
        for heading in frame.headings:
            t = msgs.ros_ns(info.epoch_utc, heading.stamp)
            out.append((MAG_TOPIC, t, msgs.magnetic_field(store, t, heading.field_ut, variance)))
            out.append((ATTITUDE_TOPIC, t, msgs.attitude(store, t, heading.roll, heading.pitch, heading.yaw)))
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
