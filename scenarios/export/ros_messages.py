"""The frame stream as ROS 2 messages (rosbags' Humble typestore, CDR), as the ROS drivers publish them.

- PointCloud2, frame `velodyne`: velodyne_pointcloud's PointcloudXYZIRT container
  (velodyne_pointcloud/src/lib/pointcloudXYZIRT.cpp, ros-drivers/velodyne branch ros2, 04a7ca7): x y z
  intensity (FLOAT32, offsets 0 4 8 12), ring (UINT16, 16: the elevation rank, 0 the lowest beam, see
  scenarios.export.dialect), time (FLOAT32, 18: seconds since the header stamp), point_step 22 (its
  fields packed without padding), little endian, height 1, is_dense (no NaN returns). The stamp is
  the revolution's start, the driver's `timestamp_first_packet: true` (its default stamps the last
  packet, and every point's time is then negative), so time runs 0 to 0.1 s.
- NavSatFix, frame `gps`: as nmea_navsat_driver writes a GGA (scenarios.export.dialect): status and
  covariance type from the GGA quality (1 -> STATUS_FIX, 2 -> STATUS_SBAS_FIX, 4 and 5 -> STATUS_GBAS_FIX,
  APPROXIMATED; 0 and 6, which it does not list -> STATUS_NO_FIX, UNKNOWN), service GPS, covariance diagonal
  (HDOP EPE)^2 east and north, (4 HDOP EPE)^2 up, EPE 4 m for quality 1 (0.1 m for 2, 0.02 m for 4, 4 m for 5,
  1e6 m when no fix), HDOP the receiver's. Latitude,
  longitude and altitude are the fix's in float64 (NaN without a position; the worlds take a geoid
  separation of 0, so altitude is the ellipsoidal height NavSatFix wants), finer than the GGA's print
  the driver would parse.
- nmea_msgs/Sentence, frame `gps`: one per NMEA sentence of a fix (GGA, RMC, GSA, GSV...), its stamp.
- gps_msgs/GPSFix, frame `gps`: the receiver's report as gpsd_client fills it
  (gpsd_client/src/client.cpp, swri-robotics/gps_umd branch ros2-devel, 4892806): the satellites
  (used PRNs; each visible one's PRN, in gpsd's numbering of all systems, sim.nmea.systems.gpsd_prn;
  elevation, azimuth and SNR as int32, truncated as its C++
  conversion does) and status always; with a solution (quality 1 or 6, gpsd's 2D/3D mode) status
  STATUS_FIX, time (UNIX seconds; the driver's own divides nanoseconds by 1e6, not copied),
  position, track (deg from north), speed (m/s) and the DOPs in float64; without one status
  STATUS_NO_FIX and the rest left at zero, as the driver leaves them. What the receiver does not
  report (climb, gdop, tdop, the error estimates) is NaN; the covariance is not filled (UNKNOWN),
  as the driver's. It carries the DOPs NavSatFix cannot.
- Imu, frame `imu_link`: as xsens_mti_driver's imupublisher.h lays it out (xsenssupport/
  Xsens_MTi_ROS_Driver_and_Ntrip_Client, e2f611d): angular velocity rad/s and linear acceleration
  m/s^2 (specific force: +g up at rest) in the IMU's axes, covariances diagonal; the simulated IMU
  has no AHRS orientation, so orientation_covariance[0] = -1 (the driver's "not available" and
  sensor_msgs/Imu's "no orientation estimate") and the orientation is the identity. The variances
  are the discrete white noise of the datasheet density N at rate f: N^2 f (Kalibr's IMU noise model,
  sigma_d = sigma / sqrt(dt); the sim draws it so, sim.sensor_noise).
- MagneticField, frame `imu_link`: the magnetometer's field in tesla as sensor_msgs/MagneticField
  wants (the Xsens driver writes its normalised units instead), covariance diagonal (noise)^2.
- QuaternionStamped, frame `imu_link`: the compass unit's orientation in ENU (its heading, true, with
  its own roll and pitch), as xsens_mti_driver publishes its filter's on /filter/quaternion.
- riverbench_msgs/GnssReport, frame `gps`: the receiver's epoch report at full precision, which NMEA
  and GPSFix round (each satellite's elevation, azimuth and C/N0 to whole degrees and dB-Hz; NMEA's
  DOPs to 1-2 decimals, speed and course to 3 and 2): GGA quality, satellites used, HDOP, VDOP, PDOP,
  speed (m/s) and course (deg from north), and per satellite in view its PRN, azimuth, elevation,
  C/N0 (0: not tracked), use in the solution, system and signal. No ROS driver publishes C/N0 finer than 1 dB-Hz;
  this type is riverbench's own, so that a replay gives the C/N0 monitor what the run gave it. Its
  definition travels in the bag (MCAP schema, rosbag2 message definitions).
- TFMessage of TransformStamped; nav_msgs/Odometry (pose and its covariance; twist not given, zero).
Time: ROS time = the scenario's UTC epoch + the simulation stamp, in integer nanoseconds.
"""

from __future__ import annotations

import math
from datetime import datetime

import numpy as np
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from rosbags.typesys.store import Typestore
from scipy.spatial.transform import Rotation

from riverbench.unixtime import scenario_unix_ns
from scenarios.export import dialect
from sim.gnss_fix import GnssFix
from sim.nmea.systems import gpsd_prn
from sim.scan import Scan

LIDAR_FRAME = "velodyne"
GPS_FRAME = "gps"
IMU_FRAME = "imu_link"
"""xsens_mti_driver's default frame_id (param/xsens_mti_node.yaml, xsenssupport/Xsens_MTi_ROS_Driver_and_Ntrip_Client e2f611d)."""
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
string[] system
string[] signal
"""
"""riverbench_msgs/msg/GnssReport: riverbench's own, see the module docstring."""
GPS_STATUS_MSG = """std_msgs/Header header
uint16 satellites_used
int32[] satellite_used_prn
uint16 satellites_visible
int32[] satellite_visible_prn
int32[] satellite_visible_z
int32[] satellite_visible_azimuth
int32[] satellite_visible_snr
int16 STATUS_NO_FIX=-1
int16 STATUS_FIX=0
int16 STATUS_SBAS_FIX=1
int16 STATUS_GBAS_FIX=2
int16 STATUS_DGPS_FIX=18
int16 STATUS_RTK_FIX=19
int16 STATUS_RTK_FLOAT=20
int16 STATUS_WAAS_FIX=33
int16 status
uint16 SOURCE_NONE=0
uint16 SOURCE_GPS=1
uint16 SOURCE_POINTS=2
uint16 SOURCE_DOPPLER=4
uint16 SOURCE_ALTIMETER=8
uint16 SOURCE_MAGNETIC=16
uint16 SOURCE_GYRO=32
uint16 SOURCE_ACCEL=64
uint16 motion_source
uint16 orientation_source
uint16 position_source
"""
"""gps_msgs/msg/GPSStatus (swri-robotics/gps_umd, gps_msgs/msg/GPSStatus.msg, ros2-devel 4892806), comments left out."""
GPS_FIX_MSG = """std_msgs/Header header
GPSStatus status
float64 latitude
float64 longitude
float64 altitude
float64 track
float64 speed
float64 climb
float64 pitch
float64 roll
float64 dip
float64 time
float64 gdop
float64 pdop
float64 hdop
float64 vdop
float64 tdop
float64 err
float64 err_horz
float64 err_vert
float64 err_track
float64 err_speed
float64 err_climb
float64 err_time
float64 err_pitch
float64 err_roll
float64 err_dip
float64[9] position_covariance
uint8 COVARIANCE_TYPE_UNKNOWN=0
uint8 COVARIANCE_TYPE_APPROXIMATED=1
uint8 COVARIANCE_TYPE_DIAGONAL_KNOWN=2
uint8 COVARIANCE_TYPE_KNOWN=3
uint8 position_covariance_type
"""
"""gps_msgs/msg/GPSFix (gps_umd, gps_msgs/msg/GPSFix.msg, ros2-devel 4892806), comments left out."""
GPS_FIX_FLOATS = tuple(line.split()[1] for line in GPS_FIX_MSG.splitlines() if line.startswith("float64 "))
"""GPSFix's float64 fields, latitude to err_dip."""
POINT = np.dtype(
    {
        "names": ["x", "y", "z", "intensity", "ring", "time"],
        "formats": ["<f4", "<f4", "<f4", "<f4", "<u2", "<f4"],
        "offsets": [0, 4, 8, 12, 16, 18],
        "itemsize": 22,
    }
)


def typestore() -> Typestore:
    """ROS 2 Humble's message types plus nmea_msgs/msg/Sentence, gps_msgs' GPSStatus and GPSFix and riverbench_msgs/msg/GnssReport
    (not in the default store)."""
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(SENTENCE_MSG, "nmea_msgs/msg/Sentence"))
    store.register(get_types_from_msg(GPS_STATUS_MSG, "gps_msgs/msg/GPSStatus"))
    store.register(get_types_from_msg(GPS_FIX_MSG, "gps_msgs/msg/GPSFix"))
    store.register(get_types_from_msg(GNSS_REPORT_MSG, GNSS_REPORT))
    return store


def ros_ns(epoch_utc: datetime, stamp: float) -> int:
    """ROS time in nanoseconds since the Unix epoch of simulation time `stamp`."""
    return scenario_unix_ns(epoch_utc, stamp)


def header(store: Typestore, ns: int, frame_id: str):
    """std_msgs/Header at `ns` nanoseconds."""
    time = store.types["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)
    return store.types["std_msgs/msg/Header"](stamp=time, frame_id=frame_id)


def point_cloud(store: Typestore, ns: int, scan: Scan):
    """The scan as the velodyne driver's PointCloud2: its whole data one PointXYZIRT buffer, rings by elevation."""
    field = store.types["sensor_msgs/msg/PointField"]
    kinds = {np.dtype("<f4"): field.FLOAT32, np.dtype("<u2"): field.UINT16}
    fields = [field(name=name, offset=offset, datatype=kinds[dtype], count=1) for name, (dtype, offset) in POINT.fields.items()]
    data = scan.points[list(POINT.names)].astype(POINT)
    data["ring"] = dialect.ring_of_laser(scan.points["ring"])
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
    """The fix as nmea_navsat_driver's NavSatFix of its GGA (see the module docstring)."""
    msg = store.types["sensor_msgs/msg/NavSatFix"]
    status, covariance_type, covariance = dialect.navsat_fields(fix.quality, fix.hdop)
    return msg(
        header=header(store, ns, GPS_FRAME),
        status=store.types["sensor_msgs/msg/NavSatStatus"](status=status, service=dialect.SERVICE_GPS),
        latitude=fix.lat,
        longitude=fix.lon,
        altitude=fix.alt,
        position_covariance=covariance,
        position_covariance_type=covariance_type,
    )


def gps_fix(store: Typestore, ns: int, fix: GnssFix):
    """The fix as gpsd_client's gps_msgs/GPSFix (see the module docstring)."""
    types = store.types
    status_type, fix_type = types["gps_msgs/msg/GPSStatus"], types["gps_msgs/msg/GPSFix"]
    used = [gpsd_prn(s.system, s.prn) for s in fix.sats if s.used]
    visible = np.array([(gpsd_prn(s.system, s.prn), s.el_deg, s.az_deg, s.snr) for s in fix.sats], dtype=np.float64).reshape(-1, 4)
    status = status_type(
        header=header(store, ns, ""),
        satellites_used=len(used),
        satellite_used_prn=np.array(used, dtype=np.int32),
        satellites_visible=len(visible),
        satellite_visible_prn=visible[:, 0].astype(np.int32),
        satellite_visible_z=np.trunc(visible[:, 1]).astype(np.int32),
        satellite_visible_azimuth=np.trunc(visible[:, 2]).astype(np.int32),
        satellite_visible_snr=np.trunc(np.nan_to_num(visible[:, 3])).astype(np.int32),
        status=status_type.STATUS_FIX if fix.valid else status_type.STATUS_NO_FIX,
        motion_source=0,
        orientation_source=0,
        position_source=0,
    )
    solved = dict(
        time=datetime.fromisoformat(fix.utc).timestamp() if fix.utc else math.nan,
        latitude=fix.lat,
        longitude=fix.lon,
        altitude=fix.alt,
        track=fix.course_deg,
        speed=fix.speed_mps,
        climb=math.nan,
        gdop=math.nan,
        pdop=fix.pdop,
        hdop=fix.hdop,
        vdop=fix.vdop,
        tdop=math.nan,
        err=math.nan,
        err_vert=math.nan,
        err_track=math.nan,
        err_speed=math.nan,
        err_climb=math.nan,
        err_time=math.nan,
    )
    values = {name: solved.get(name, 0.0) if fix.valid else 0.0 for name in GPS_FIX_FLOATS}
    return fix_type(
        header=header(store, ns, GPS_FRAME),
        status=status,
        position_covariance=np.zeros(9),
        position_covariance_type=fix_type.COVARIANCE_TYPE_UNKNOWN,
        **values,
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
        system=[s.system for s in sats],
        signal=[s.signal for s in sats],
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


def odometry(store: Typestore, ns: int, pose: np.ndarray, child: str, covariance: np.ndarray | None = None):
    """nav_msgs/Odometry map -> `child` of a 4x4 pose with its 6x6 covariance [x y z roll pitch yaw] (zero when
    not given, as for the exact truth); twist not given (zero)."""
    types = store.types
    x, y, z = pose[:3, 3]
    position = types["geometry_msgs/msg/Point"](x=x, y=y, z=z)
    zero = types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
    return types["nav_msgs/msg/Odometry"](
        header=header(store, ns, MAP_FRAME),
        child_frame_id=child,
        pose=types["geometry_msgs/msg/PoseWithCovariance"](
            pose=types["geometry_msgs/msg/Pose"](position=position, orientation=quaternion(store, pose)),
            covariance=np.zeros(36) if covariance is None else np.asarray(covariance, dtype=np.float64).ravel(),
        ),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](
            twist=types["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36)
        ),
    )


def vector3(store: Typestore, xyz) -> object:
    """geometry_msgs/Vector3 of three numbers."""
    x, y, z = (float(v) for v in xyz)
    return store.types["geometry_msgs/msg/Vector3"](x=x, y=y, z=z)


def diagonal(variance: float) -> np.ndarray:
    """A 3x3 row-major covariance with `variance` on its diagonal."""
    return np.diag(np.full(3, float(variance))).ravel()


def imu(store: Typestore, ns: int, gyro, accel, gyro_variance: float, accel_variance: float):
    """sensor_msgs/Imu of one sample without orientation (see the module docstring)."""
    no_orientation = np.zeros(9)
    no_orientation[0] = -1.0
    return store.types["sensor_msgs/msg/Imu"](
        header=header(store, ns, IMU_FRAME),
        orientation=store.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=no_orientation,
        angular_velocity=vector3(store, gyro),
        angular_velocity_covariance=diagonal(gyro_variance),
        linear_acceleration=vector3(store, accel),
        linear_acceleration_covariance=diagonal(accel_variance),
    )


def attitude(store: Typestore, ns: int, roll: float, pitch: float, yaw: float):
    """geometry_msgs/QuaternionStamped of an AHRS's orientation (imu_link in ENU; roll, pitch, yaw as z-y'-x'' Euler angles)."""
    x, y, z, w = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_quat()
    return store.types["geometry_msgs/msg/QuaternionStamped"](
        header=header(store, ns, IMU_FRAME), quaternion=store.types["geometry_msgs/msg/Quaternion"](x=x, y=y, z=z, w=w)
    )


def magnetic_field(store: Typestore, ns: int, field_ut, variance_t2: float):
    """sensor_msgs/MagneticField of one magnetometer output (field in microtesla -> tesla)."""
    return store.types["sensor_msgs/msg/MagneticField"](
        header=header(store, ns, IMU_FRAME),
        magnetic_field=vector3(store, np.asarray(field_ut, dtype=float) * 1e-6),
        magnetic_field_covariance=diagonal(variance_t2),
    )
