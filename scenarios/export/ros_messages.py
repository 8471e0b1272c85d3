"""The frame stream as ROS 2 messages (rosbags' Humble typestore, CDR), as the ROS drivers publish them.

- PointCloud2, frame `velodyne`: the velodyne_pointcloud driver's PointXYZIRT layout, x y z intensity
  (float32, offsets 0 4 8 12), ring (uint16, 16), time (float32, 18: seconds since the header stamp),
  point_step 22, little endian, height 1, is_dense (no NaN returns); stamp = the revolution's start.
- NavSatFix, frame `gps`: the fix's lat, lon and alt (NaN without a fix; the worlds take a geoid
  separation of 0, so the altitude is also the ellipsoidal height NavSatFix wants), service GPS, and
  as nmea_navsat_driver maps GGA quality: 1 -> STATUS_FIX with position_covariance diagonal in ENU,
  east and north (HDOP * UERE)^2 / 2 (HDOP * UERE is the horizontal DRMS), up (VDOP * UERE)^2,
  COVARIANCE_TYPE_APPROXIMATED, UERE = 4 m (the driver's default error of a standalone GPS fix: a
  receiver-agnostic figure, not the simulator's own noise); 0 -> STATUS_NO_FIX, covariance zero,
  COVARIANCE_TYPE_UNKNOWN; 6 (dead reckoning) -> the same as 0, as the driver maps every quality it
  does not list, the receiver's coasting position still filled in: it solved nothing, and consumers
  such as robot_localization's navsat_transform then skip it.
- nmea_msgs/Sentence, frame `gps`: one per NMEA sentence of a fix (GGA, RMC, GSA, GSV...), its stamp.
- riverbench_msgs/GnssReport, frame `gps`: the receiver's epoch report at full precision, which NMEA
  prints rounded (DOPs to 1-2 decimals, each satellite's elevation, azimuth and C/N0 to whole degrees
  and dB-Hz, speed and course to 3 and 2 decimals): GGA quality, satellites used, HDOP, VDOP, PDOP,
  speed (m/s) and course (deg from north), and per satellite in view its PRN, azimuth, elevation,
  C/N0 (0: not tracked) and use in the solution. No ROS driver publishes C/N0 finer than 1 dB-Hz;
  this topic is riverbench's own, so that a replay gives the C/N0 monitor what the run gave it. The
  type's definition travels in the bag (MCAP schema, rosbag2 message definitions).
- TFMessage of TransformStamped and nav_msgs/Odometry (pose only: covariance and twist left zero).
Time: ROS time = the scenario's UTC epoch + the simulation stamp, in integer nanoseconds.
"""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore
from scipy.spatial.transform import Rotation

from sim.gnss_fix import GnssFix
from sim.scan import Scan

LIDAR_FRAME = "velodyne"
GPS_FRAME = "gps"
BASE_FRAME = "base_link"
MAP_FRAME = "map"
SENTENCE_MSG = "std_msgs/Header header\nstring sentence\n"
GNSS_REPORT = "riverbench_msgs/msg/GnssReport"
GNSS_REPORT_MSG = """std_msgs/Header header
int16 quality
uint16 num_sats
float64 hdop
float64 vdop
float64 pdop
float64 speed_mps
float64 course_deg
uint16[] prn
float64[] azimuth_deg
float64[] elevation_deg
float64[] cn0_dbhz
bool[] used
"""
POINT = np.dtype(
    {
        "names": ["x", "y", "z", "intensity", "ring", "time"],
        "formats": ["<f4", "<f4", "<f4", "<f4", "<u2", "<f4"],
        "offsets": [0, 4, 8, 12, 16, 18],
        "itemsize": 22,
    }
)
UERE_M = 4.0
UNIX_EPOCH = datetime(1970, 1, 1, tzinfo=UTC)


def typestore() -> Typestore:
    """ROS 2 Humble's message types plus nmea_msgs/msg/Sentence and riverbench_msgs/msg/GnssReport (not in the default store)."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(SENTENCE_MSG, "nmea_msgs/msg/Sentence"))
    store.register(get_types_from_msg(GNSS_REPORT_MSG, GNSS_REPORT))
    return store


def ros_ns(epoch_utc: datetime, stamp: float) -> int:
    """ROS time in nanoseconds since the Unix epoch of simulation time `stamp`."""
    return (epoch_utc - UNIX_EPOCH) // timedelta(microseconds=1) * 1000 + round(stamp * 1e9)


def header(store: Typestore, ns: int, frame_id: str):
    """std_msgs/Header at `ns` nanoseconds."""
    time = store.types["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
    return store.types["std_msgs/msg/Header"](stamp=time, frame_id=frame_id)


def point_cloud(store: Typestore, ns: int, scan: Scan):
    """The scan as the velodyne driver's PointCloud2: its whole data one PointXYZIRT buffer."""
    field = store.types["sensor_msgs/msg/PointField"]
    kinds = {np.dtype("<f4"): field.FLOAT32, np.dtype("<u2"): field.UINT16}
    fields = [field(name=name, offset=offset, datatype=kinds[dtype], count=1) for name, (dtype, offset) in POINT.fields.items()]
    data = scan.points[list(POINT.names)].astype(POINT)
    return store.types["sensor_msgs/msg/PointCloud2"](
        header=header(store, ns, LIDAR_FRAME),
        height=1,
        width=len(data),
        fields=fields,
        is_bigendian=False,
        point_step=POINT.itemsize,
        row_step=POINT.itemsize * len(data),
        data=data.view(np.uint8),
        is_dense=True,
    )


def nav_sat_fix(store: Typestore, ns: int, fix: GnssFix):
    """The fix as NavSatFix: status from its GGA quality, covariance from its DOPs when it has a fix (see the module docstring)."""
    msg = store.types["sensor_msgs/msg/NavSatFix"]
    status = store.types["sensor_msgs/msg/NavSatStatus"]
    fixed = fix.quality == 1
    variances = [(fix.hdop * UERE_M) ** 2 / 2.0, (fix.hdop * UERE_M) ** 2 / 2.0, (fix.vdop * UERE_M) ** 2] if fixed else [0.0] * 3
    return msg(
        header=header(store, ns, GPS_FRAME),
        status=status(status=status.STATUS_FIX if fixed else status.STATUS_NO_FIX, service=status.SERVICE_GPS),
        latitude=fix.lat,
        longitude=fix.lon,
        altitude=fix.alt,
        position_covariance=np.diag(variances).ravel(),
        position_covariance_type=msg.COVARIANCE_TYPE_APPROXIMATED if fixed else msg.COVARIANCE_TYPE_UNKNOWN,
    )


def sentences(store: Typestore, ns: int, fix: GnssFix) -> list:
    """One nmea_msgs/Sentence per NMEA sentence of the fix."""
    return [store.types["nmea_msgs/msg/Sentence"](header=header(store, ns, GPS_FRAME), sentence=text) for text in fix.nmea()]


def gnss_report(store: Typestore, ns: int, fix: GnssFix):
    """The fix's receiver report at full precision (riverbench_msgs/GnssReport, see the module docstring)."""
    sats = fix.sats
    return store.types[GNSS_REPORT](
        header=header(store, ns, GPS_FRAME),
        quality=int(fix.quality),
        num_sats=int(fix.num_sats),
        hdop=float(fix.hdop),
        vdop=float(fix.vdop),
        pdop=float(fix.pdop),
        speed_mps=float(fix.speed_mps),
        course_deg=float(fix.course_deg),
        prn=np.array([s.prn for s in sats], dtype=np.uint16),
        azimuth_deg=np.array([s.az_deg for s in sats], dtype=np.float64),
        elevation_deg=np.array([s.el_deg for s in sats], dtype=np.float64),
        cn0_dbhz=np.array([s.snr for s in sats], dtype=np.float64),
        used=np.array([s.used for s in sats], dtype=bool),
    )


def quaternion(store: Typestore, pose: np.ndarray):
    """geometry_msgs/Quaternion of a 4x4 pose's rotation."""
    x, y, z, w = Rotation.from_matrix(pose[:3, :3]).as_quat()
    return store.types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)


def transform(store: Typestore, ns: int, parent: str, child: str, pose: np.ndarray):
    """geometry_msgs/TransformStamped parent <- child of a 4x4 pose."""
    x, y, z = pose[:3, 3]
    translation = store.types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)
    return store.types["geometry_msgs/msg/TransformStamped"](
        header=header(store, ns, parent),
        child_frame_id=child,
        transform=store.types["geometry_msgs/msg/Transform"](translation=translation, rotation=quaternion(store, pose)),
    )


def tf_message(store: Typestore, transforms: list):
    """tf2_msgs/TFMessage of the transforms."""
    return store.types["tf2_msgs/msg/TFMessage"](transforms=transforms)


def odometry(store: Typestore, ns: int, pose: np.ndarray):
    """nav_msgs/Odometry map -> base_link of a 4x4 pose: exact, so covariance zero; twist not given (zero)."""
    types = store.types
    x, y, z = pose[:3, 3]
    position = types["geometry_msgs/msg/Point"](x=x, y=y, z=z)
    zero = types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    return types["nav_msgs/msg/Odometry"](
        header=header(store, ns, MAP_FRAME),
        child_frame_id=BASE_FRAME,
        pose=types["geometry_msgs/msg/PoseWithCovariance"](
            pose=types["geometry_msgs/msg/Pose"](position=position, orientation=quaternion(store, pose)), covariance=np.zeros(36)
        ),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](
            twist=types["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36)
        ),
    )
