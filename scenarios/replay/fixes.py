"""Receiver reports read back into the GnssFix the estimators take (fusion.observation.screen reads stamp,
quality, enu, hdop, vdop and the satellites' prn, elevation, C/N0 and use), with no truth.

- NMEA (nmea_msgs/Sentence, a pcap's GPRMC): one epoch's sentences are decoded by sim.nmea's
  parser; GGA gives position, quality, satellites used, HDOP and altitude, GSA the used PRNs and
  the DOPs, GSV each satellite's elevation, azimuth and C/N0, RMC speed, course and, without GGA,
  position and quality (status V -> 0, mode E -> 6 dead reckoning, else 1). Sentences of other
  types or with a bad checksum stay in the log and are not read. An epoch is the run of sentences
  from one GGA/RMC time to the next.
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
  NavSatFix of unknown covariance) gets HDOP NOMINAL_HDOP, an open-sky receiver's: the estimators
  weigh it as such (uere_m * 1.0 / sqrt(2) per axis), the hdop monitor always trusts it and the
  C/N0 monitor cannot judge it; without HDOP every estimator would refuse every fix. Without an
  altitude (GPRMC, or an empty GGA field) the fix is put at the ENU origin's height.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Iterable

import numpy as np

from scenarios.export import dialect
from scenarios.replay.recording import Geo
from sim import nmea
from sim.gnss_fix import GnssFix, SatelliteReport

NOMINAL_HDOP = 1.0
NAVSAT_QUALITY = {-1: 0, 0: 1, 1: 2, 2: 4}
"""NavSatStatus (NO_FIX, FIX, SBAS_FIX, GBAS_FIX) -> GGA quality."""
TIMED = ("GGA", "RMC")
REFINE_M = 0.1


class Epochs:
    """Split a stream of NMEA sentences into receiver epochs: add() returns the epoch the sentence closed, if any."""

    def __init__(self) -> None:
        self._stamps: list[int] = []
        self._lines: list[str] = []
        self._time = ""

    @property
    def open_ns(self) -> int | None:
        """Stamp (ns) of the epoch being collected (None when none is open)."""
        return self._stamps[0] if self._stamps else None

    def add(self, ns: int, line: str) -> tuple[list[int], list[str]] | None:
        """Take one sentence stamped `ns`; a GGA or RMC of a new time closes the open epoch and returns it (stamps, sentences)."""
        line = line.strip()
        time = utc_field(line)
        closed = self.close() if time and self._time and time != self._time else None
        self._time = time or self._time
        self._stamps.append(ns)
        self._lines.append(line)
        return closed

    def close(self) -> tuple[list[int], list[str]] | None:
        """The open epoch (and none is open after), or None."""
        if not self._stamps:
            return None
        epoch = (self._stamps, self._lines)
        self._stamps, self._lines, self._time = [], [], ""
        return epoch


def utc_field(line: str) -> str:
    """The hhmmss.ss field of a GGA or RMC sentence ('' for any other line)."""
    fields = line.split(",")
    return fields[1] if len(fields) > 1 and fields[0][-3:] in TIMED and fields[0].startswith("$") else ""


def decoded(lines: Iterable[str]) -> list[dict]:
    """The sentences sim.nmea can decode (GGA, RMC, GSA, GSV with a good checksum), in order; the rest skipped."""
    out = []
    for line in lines:
        try:
            out.append(nmea.parse(line))
        except ValueError:
            continue
    return out


def from_nmea(stamp: float, lines: list[str], geo: Geo) -> GnssFix | None:
    """The epoch's fix (None when it has neither GGA nor RMC)."""
    messages = decoded(lines)
    kinds: dict[str, list[dict]] = {}
    for m in messages:
        kinds.setdefault(m["type"], []).append(m)
    gga, rmc = (kinds.get(k, [None])[0] for k in TIMED)
    if gga is None and rmc is None:
        return None
    gsa = kinds.get("GSA", [])
    used = {prn for m in gsa for prn in m["prns"]}
    sats = tuple(
        SatelliteReport(prn, float(az), float(el), float(snr or 0.0), prn in used) for m in kinds.get("GSV", []) for prn, el, az, snr in m["sats"]
    )
    if gga is not None:
        quality, lat, lon, alt, num_sats = gga["quality"], gga["lat"], gga["lon"], gga["alt"], gga["num_sats"]
    else:
        quality = 0 if not rmc["valid"] else {"N": 0, "E": 6}.get(rmc["mode"], 1)
        lat, lon, alt, num_sats = rmc["lat"], rmc["lon"], math.nan, len(used)
    if math.isfinite(lat) and not math.isfinite(alt):
        alt = geo.origin[2]
    dops = [m["hdop"] for m in (gga, *gsa) if m is not None]
    hdop = next((h for h in dops if math.isfinite(h)), math.nan) if dops else NOMINAL_HDOP
    return fix(
        stamp,
        geo,
        quality,
        lat,
        lon,
        alt,
        num_sats,
        hdop,
        vdop=gsa[0]["vdop"] if gsa else math.nan,
        pdop=gsa[0]["pdop"] if gsa else math.nan,
        sats=sats,
        speed_mps=rmc["speed_mps"] if rmc else math.nan,
        course_deg=rmc["course_deg"] if rmc else math.nan,
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
