"""Receiver reports read back into the GnssFix the estimators take (fusion.observation.screen reads stamp,
quality, enu, hdop, vdop and the satellites' prn, elevation, C/N0, use, system and signal), with no truth.

- NMEA (an NMEA log, nmea_msgs/Sentence, a pcap's GPRMC): sentences are read and cut into epochs
  by sim.nmea (any talker; GGA, RMC, GNS, GLL, GSA, GSV, VTG, ZDA, GST; epochs by fix time value);
  each epoch is one fix, a no-fix epoch too (quality 0, no position): position, height, quality,
  satellites used, DOPs, speed and course as sim.nmea.epochs merges them, every satellite signal
  of its GSVs with its system and signal, used when a GSA lists it. Lines that are not read
  (bad or missing checksum, garbage, proprietary, other types) stay in the log and are counted.
- NavSatFix: latitude, longitude, altitude; status NO_FIX -> 0, FIX -> 1, SBAS -> 2, GBAS -> 4;
  HDOP from a known covariance by nmea_navsat_driver's convention, sqrt((var_east + var_north) / 2)
  / EPE of the status (scenarios.export.dialect.hdop_of_navsat: exact for that driver's and
  riverbench's bags; other drivers' conventions give an equivalent HDOP); no VDOP (the convention
  carries none). No satellites, so the C/N0 monitor cannot judge, and no dead reckoning (6).
- Both (a bag with NMEA and one NavSatFix topic, as riverbench's export and nmea_navsat_driver
  record them): the NMEA epoch's fix, with the position of the NavSatFix stamped like one of its
  sentences in float64 (NMEA prints 5 decimals of minutes, ~1 cm) when it lies within REFINE_M,
  and that NavSatFix's HDOP when it prints as the NMEA one (another covariance convention is left
  alone). A gps_msgs/GPSFix stamped like the epoch (gpsd_client's, riverbench's export) gives its
  float64 HDOP, VDOP and PDOP when its HDOP and VDOP print as NMEA's; else VDOP and PDOP stay GSA's.
  The satellites' C/N0 (1 dB-Hz) and elevation (1 deg) stay NMEA's integers.
- An epoch that reports no DOP at all (GPRMC alone, as a Velodyne's position packets carry it, or a
  NavSatFix of unknown covariance) gets HDOP NOMINAL_HDOP, an open-sky receiver's, when it is a
  satellite solution (quality 1, 2, 4, 5; any other has none: NaN): the estimators weigh it as such (uere_m * 1.0 / sqrt(2) per
  axis), the hdop monitor always trusts it and the C/N0 monitor cannot judge it; without HDOP every
  estimator would refuse every fix. A dead-reckoning epoch (RMC mode E, quality 6) has no satellite
  geometry and gets none (NaN), as the receiver's own GGA leaves it empty: the monitors refuse it as
  they do in a run (a pcap's GPRMC coast was trusted before, 45 gps_only verdicts off on a round trip). Without an
  altitude (GPRMC, or an empty GGA field) the fix is put at the ENU origin's height.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from scenarios.export import dialect
from scenarios.replay.recording import Geo
from sim.gnss_fix import GnssFix, SatelliteReport
from sim.nmea import epochs
from sim.nmea.read import Record, Skipped, read

NOMINAL_HDOP = 1.0
SATELLITE_SOLUTIONS = frozenset({1, 2, 4, 5})
"""GGA qualities of a position solved from satellites (not 0 no fix, not 6 dead reckoning)."""
NAVSAT_QUALITY = {-1: 0, 0: 1, 1: 2, 2: 4}
"""NavSatStatus (NO_FIX, FIX, SBAS_FIX, GBAS_FIX) -> GGA quality."""
HDOP_KINDS = frozenset({"GGA", "GNS", "GSA"})
"""Sentences with an HDOP field: an epoch with one of them has the HDOP they give (NaN when they leave it empty)."""
REFINE_M = 0.1


def from_nmea(stamp: float, lines: list[str], geo: Geo) -> GnssFix | None:
    """The fix of one epoch's sentences (None when none of them gives a fix time or position: GGA, RMC, GNS, GLL)."""
    return from_epoch(stamp, epochs.assemble([epochs.Line(k, line, read_or_none(line)) for k, line in enumerate(lines)]), geo)


def read_or_none(line: str) -> Record | None:
    """The sentence's record, None when it is not read."""
    try:
        return read(line)
    except Skipped:
        return None


def from_epoch(stamp: float, epoch: epochs.Epoch, geo: Geo) -> GnssFix | None:
    """The fix of an NMEA epoch (None when it has no GGA, RMC, GNS or GLL)."""
    if not epoch.kinds & set(epochs.POSITIONS):
        return None
    sats = tuple(SatelliteReport(s.svid, s.az_deg, s.el_deg, 0.0 if math.isnan(s.snr) else s.snr, s.used, s.system, s.signal) for s in epoch.sats)
    alt = epoch.alt if math.isfinite(epoch.alt) or not math.isfinite(epoch.lat) else geo.origin[2]
    hdop = epoch.hdop if epoch.kinds & HDOP_KINDS else NOMINAL_HDOP if epoch.quality in SATELLITE_SOLUTIONS else math.nan
    return fix(
        stamp,
        geo,
        epoch.quality,
        epoch.lat,
        epoch.lon,
        alt,
        epoch.num_sats,
        hdop,
        vdop=epoch.vdop,
        pdop=epoch.pdop,
        sats=sats,
        speed_mps=epoch.speed_mps,
        course_deg=epoch.course_deg,
    )


def from_navsatfix(stamp: float, msg, geo: Geo) -> GnssFix:
    """A sensor_msgs/NavSatFix's fix (see the module docstring for status and covariance)."""
    hdop, vdop = navsat_dops(msg)
    return fix(
        stamp, geo, NAVSAT_QUALITY.get(int(msg.status.status), 0), float(msg.latitude), float(msg.longitude), float(msg.altitude), 0, hdop, vdop=vdop
    )


def navsat_dops(msg) -> tuple[float, float]:
    """(HDOP, VDOP) of a NavSatFix: HDOP from its covariance (module docstring; NOMINAL_HDOP when unknown), VDOP NaN."""
    hdop = dialect.hdop_of_navsat(msg.status.status, msg.position_covariance_type, msg.position_covariance)
    return NOMINAL_HDOP if hdop is None else hdop, math.nan


def refined(fix: GnssFix, navsat, extended, geo: Geo) -> GnssFix:
    """The NMEA fix with the float64 position and HDOP of a NavSatFix of its epoch and the float64 DOPs of a GPSFix
    of its epoch (either may be None), each when it agrees with NMEA (module docstring)."""
    if not fix.quality:
        return fix
    out = fix
    if navsat is not None:
        lat, lon, alt = float(navsat.latitude), float(navsat.longitude), float(navsat.altitude)
        enu = geo.enu(lat, lon, alt)
        if np.isfinite(enu).all() and np.linalg.norm(enu[:2] - fix.enu[:2]) <= REFINE_M:
            hdop = navsat_dops(navsat)[0]
            out = dataclasses.replace(out, lat=lat, lon=lon, alt=alt, enu=enu, hdop=hdop if f"{hdop:.2f}" == f"{fix.hdop:.2f}" else fix.hdop)
    if extended is not None and all(f"{float(getattr(extended, k)):.2f}" == f"{getattr(fix, k):.2f}" for k in ("hdop", "vdop")):
        out = dataclasses.replace(out, hdop=float(extended.hdop), vdop=float(extended.vdop), pdop=float(extended.pdop))
    return out


def fix(
    stamp: float,
    geo: Geo,
    quality: int,
    lat: float,
    lon: float,
    alt: float,
    num_sats: int,
    hdop: float,
    *,
    vdop: float = math.nan,
    pdop: float = math.nan,
    sats: tuple[SatelliteReport, ...] = (),
    speed_mps: float = math.nan,
    course_deg: float = math.nan,
) -> GnssFix:
    """A GnssFix of reported values: ENU from the position (NaN without one or without a fix), UTC from the stamp, no truth."""
    position = quality != 0 and all(math.isfinite(v) for v in (lat, lon, alt))
    enu = geo.enu(lat, lon, alt) if position else np.full(3, np.nan)
    quality = quality if position else 0
    utc = geo.utc(stamp).isoformat(timespec="microseconds")
    return GnssFix(
        stamp=stamp,
        lat=lat,
        lon=lon,
        alt=alt,
        enu=enu,
        quality=quality,
        num_sats=num_sats,
        hdop=hdop,
        vdop=vdop,
        pdop=pdop,
        sats=sats,
        utc=utc,
        speed_mps=speed_mps,
        course_deg=course_deg,
    )
