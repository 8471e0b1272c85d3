"""The ROS drivers' conventions a bag speaks, one definition each, used by the export that writes them and the replay that reads them.

- Ring: velodyne_pointcloud numbers the rings of a cloud by elevation, 0 the lowest beam
  (velodyne_pointcloud/src/lib/calibration.cpp sorts the calibration's vert_correction ascending
  into `laser_ring`; ros-drivers/velodyne, branch ros2, 04a7ca7). sim's Scan numbers them by laser
  id (firing order); `ring_of_laser` and `laser_of_ring` map between the two with the HDL-32E's
  elevation table (sim.HDL32E.elevation_deg).
- NavSatFix: nmea_navsat_driver's mapping of a GGA (libnmea_navsat_driver/driver.py,
  ros-drivers/nmea_navsat_driver, branch ros2, 548c84a): the GGA quality picks a default estimated
  position error (EPE, metres), a NavSatStatus and a covariance type; the position covariance is
  diagonal, east and north (HDOP * EPE)^2, up (2 * HDOP * 2 * EPE)^2 (the driver's alt_std_dev =
  2 * EPE, doubled again in its covariance; it carries no VDOP). A quality it does not list (3 PPS,
  6 dead reckoning, 7, 8) is its "unknown" -1: no fix, covariance type unknown, EPE 1e6 m.
  `navsat_fields` writes that, `hdop_of_navsat` reads the HDOP back.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim import HDL32E

RING_OF_LASER = np.argsort(np.argsort(HDL32E.elevation_deg, kind="stable"), kind="stable").astype(np.uint16)
"""Elevation rank (velodyne_pointcloud's ring, 0 lowest) of each HDL-32E laser id."""
LASER_OF_RING = np.argsort(HDL32E.elevation_deg, kind="stable").astype(np.uint16)
"""HDL-32E laser id of each elevation rank (the inverse of RING_OF_LASER)."""

STATUS_NO_FIX, STATUS_FIX, STATUS_SBAS_FIX, STATUS_GBAS_FIX = -1, 0, 1, 2
"""sensor_msgs/NavSatStatus status values."""
SERVICE_GPS = 1
"""sensor_msgs/NavSatStatus service: GPS (what nmea_navsat_driver always writes)."""
COVARIANCE_TYPE_UNKNOWN, COVARIANCE_TYPE_APPROXIMATED = 0, 1
"""sensor_msgs/NavSatFix position_covariance_type values."""


@dataclass(frozen=True)
class GgaQuality:
    """What nmea_navsat_driver derives from a GGA quality (its `gps_qualities` table and epe_quality* defaults)."""

    epe_m: float
    status: int
    covariance_type: int


NMEA_NAVSAT_QUALITIES = {
    -1: GgaQuality(1_000_000.0, STATUS_NO_FIX, COVARIANCE_TYPE_UNKNOWN),  # a quality the driver does not list
    0: GgaQuality(1_000_000.0, STATUS_NO_FIX, COVARIANCE_TYPE_UNKNOWN),  # invalid
    1: GgaQuality(4.0, STATUS_FIX, COVARIANCE_TYPE_APPROXIMATED),  # SPS
    2: GgaQuality(0.1, STATUS_SBAS_FIX, COVARIANCE_TYPE_APPROXIMATED),  # DGPS
    4: GgaQuality(0.02, STATUS_GBAS_FIX, COVARIANCE_TYPE_APPROXIMATED),  # RTK fixed
    5: GgaQuality(4.0, STATUS_GBAS_FIX, COVARIANCE_TYPE_APPROXIMATED),  # RTK float
    9: GgaQuality(3.0, STATUS_GBAS_FIX, COVARIANCE_TYPE_APPROXIMATED),  # WAAS
}
"""GGA quality -> nmea_navsat_driver's (EPE, status, covariance type), its parameters' defaults."""
GGA_OF_STATUS = {STATUS_NO_FIX: 0, STATUS_FIX: 1, STATUS_SBAS_FIX: 2, STATUS_GBAS_FIX: 4}
"""NavSatStatus -> the GGA quality it most likely came from (GBAS: RTK fixed, the driver's 4)."""


def ring_of_laser(laser: np.ndarray) -> np.ndarray:
    """velodyne_pointcloud's ring (elevation rank, 0 lowest) of HDL-32E laser ids."""
    return RING_OF_LASER[np.asarray(laser, dtype=np.intp)]


def laser_of_ring(ring: np.ndarray) -> np.ndarray:
    """HDL-32E laser ids of velodyne_pointcloud rings (elevation ranks)."""
    return LASER_OF_RING[np.asarray(ring, dtype=np.intp)]


def gga_quality(quality: int) -> GgaQuality:
    """nmea_navsat_driver's reading of a GGA quality (an unlisted one is its 'unknown')."""
    return NMEA_NAVSAT_QUALITIES.get(int(quality), NMEA_NAVSAT_QUALITIES[-1])


def navsat_fields(quality: int, hdop: float) -> tuple[int, int, np.ndarray]:
    """(status, position_covariance_type, position_covariance (9,), row-major ENU) as nmea_navsat_driver writes them
    for a GGA of this quality and HDOP (NaN HDOP, an empty GGA field, gives a NaN covariance, as the driver's)."""
    table = gga_quality(quality)
    horizontal = (hdop * table.epe_m) ** 2
    up = (2.0 * hdop * 2.0 * table.epe_m) ** 2
    return table.status, table.covariance_type, np.diag([horizontal, horizontal, up]).ravel()


def hdop_of_navsat(status: int, covariance_type: int, covariance) -> float | None:
    """The HDOP a NavSatFix's covariance gives under nmea_navsat_driver's convention (the east and north variances'
    mean over the status's EPE squared, exact for its messages); None without a fix or a known covariance."""
    cov = np.asarray(covariance, dtype=float).reshape(3, 3)
    if int(status) == STATUS_NO_FIX or int(covariance_type) == COVARIANCE_TYPE_UNKNOWN:
        return None
    horizontal = (cov[0, 0] + cov[1, 1]) / 2.0
    if not math.isfinite(horizontal) or horizontal <= 0:
        return None
    return math.sqrt(horizontal) / gga_quality(GGA_OF_STATUS.get(int(status), 1)).epe_m
