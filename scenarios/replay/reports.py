"""riverbench's own receiver report (riverbench_msgs/GnssReport, scenarios.export.ros_messages) laid over a fix read from
NMEA or NavSatFix: the quality, DOPs, speed, course and satellites (elevation, azimuth, C/N0) as the receiver gave
them, unrounded, so that the estimators and their monitors see in a replay what they saw in the simulated run."""

from __future__ import annotations

import math

from scenarios.replay import fixes
from scenarios.replay.recording import Geo
from sim.gnss_fix import GnssFix, SatelliteReport


def applied(fix: GnssFix, msg, geo: Geo) -> GnssFix:
    """The fix (its stamp and position) with the report's quality, DOPs, speed, course and satellites."""
    columns = (msg.prn, msg.azimuth_deg, msg.elevation_deg, msg.cn0_dbhz, msg.used, msg.system, msg.signal)
    sats = tuple(
        SatelliteReport(int(prn), float(az), float(el), float(cn0), bool(used), str(system), str(signal))
        for prn, az, el, cn0, used, system, signal in zip(*columns, strict=True)
    )
    quality = int(msg.quality) if all(math.isfinite(v) for v in (fix.lat, fix.lon, fix.alt)) else 0
    return fixes.fix(
        fix.stamp,
        geo,
        quality,
        fix.lat,
        fix.lon,
        fix.alt,
        int(msg.num_sats),
        float(msg.hdop),
        vdop=float(msg.vdop),
        pdop=float(msg.pdop),
        sats=sats,
        speed_mps=float(msg.speed_mps),
        course_deg=float(msg.course_deg),
    )
