"""NMEA 0183 (v2.3) sentences the simulated GPS receiver writes per epoch (GGA, RMC, GSA, GSV).

Talker "GP" (GPS only). Latitude/longitude carry 5 decimals of minutes (~2 cm), time 2 decimals of
seconds, as common consumer receivers write them. GGA's altitude field holds the fix's altitude
with a geoid separation of 0 (the worlds' heights are taken as orthometric). sim.nmea.read reads
them back (and what real receivers write).

The writers take any object with the fields they read (`Fix`, `Satellite`: sim.gnss_fix's GnssFix and
SatelliteReport have them), so this module imports nothing of the receiver's and GnssFix.nmea() can use it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from datetime import datetime, timedelta
from functools import reduce
from typing import Protocol

TALKER = "GP"
KNOT_MPS = 1852.0 / 3600.0
MAX_GSA_PRNS = 12
SATS_PER_GSV = 4


class Satellite(Protocol):
    """What GSA and GSV read of a satellite in view (sim.gnss_fix.SatelliteReport)."""

    @property
    def prn(self) -> int: ...
    @property
    def az_deg(self) -> float: ...
    @property
    def el_deg(self) -> float: ...
    @property
    def snr(self) -> float: ...
    @property
    def used(self) -> bool: ...


class Fix(Protocol):
    """What the sentences read of one receiver epoch (sim.gnss_fix.GnssFix)."""

    @property
    def utc(self) -> str: ...
    @property
    def lat(self) -> float: ...
    @property
    def lon(self) -> float: ...
    @property
    def alt(self) -> float: ...
    @property
    def quality(self) -> int: ...
    @property
    def num_sats(self) -> int: ...
    @property
    def hdop(self) -> float: ...
    @property
    def vdop(self) -> float: ...
    @property
    def pdop(self) -> float: ...
    @property
    def speed_mps(self) -> float: ...
    @property
    def course_deg(self) -> float: ...
    @property
    def sats(self) -> Sequence[Satellite]: ...


def checksum(body: str) -> str:
    """XOR of all characters between '$' and '*', as two upper-case hex digits."""
    return f"{reduce(lambda acc, ch: acc ^ ord(ch), body, 0):02X}"


def sentence(body: str) -> str:
    """'$' + body + '*' + checksum."""
    return f"${body}*{checksum(body)}"


def _num(value: float, fmt: str) -> str:
    return "" if value is None or not math.isfinite(value) else format(value, fmt)


def _angle(value: float, degree_digits: int, hemispheres: str) -> tuple[str, str]:
    """(d)ddmm.mmmmm and hemisphere letter, rounded so that minutes never print as 60."""
    if not math.isfinite(value):
        return "", ""
    total = round(abs(value) * 60.0 * 1e5)
    degrees, minutes = divmod(total, 60 * 100_000)
    return f"{degrees:0{degree_digits}d}{minutes / 1e5:08.5f}", hemispheres[0] if value >= 0 else hemispheres[1]


def _utc(fix: Fix) -> datetime:
    """The fix's UTC rounded to the 0.01 s that NMEA carries."""
    when = datetime.fromisoformat(fix.utc) + timedelta(microseconds=5000)
    return when.replace(microsecond=when.microsecond // 10_000 * 10_000)


def _time(when: datetime) -> str:
    return f"{when:%H%M%S}.{when.microsecond // 10_000:02d}"


def _differential(fix: Fix) -> tuple[str, str]:
    """GGA fields 13 and 14: age of the differential corrections (s, 1 decimal) and reference station id (4 digits),
    both empty unless the fix is differential (quality 2, 4, 5) and carries them (GnssFix.correction_age_s, .station_id)."""
    age = getattr(fix, "correction_age_s", math.nan)
    station = getattr(fix, "station_id", None)
    if fix.quality not in (2, 4, 5) or age is None or not math.isfinite(age):
        return "", ""
    return f"{age:.1f}", "" if station is None else f"{station:04d}"


def gga(fix: Fix) -> str:
    """Fix data: time, position, quality, satellites used, HDOP, altitude, age of corrections and their station."""
    valid = fix.quality != 0
    lat, ns = _angle(fix.lat if valid else math.nan, 2, "NS")
    lon, ew = _angle(fix.lon if valid else math.nan, 3, "EW")
    alt = _num(fix.alt if valid else math.nan, ".2f")
    age, station = _differential(fix)
    body = (
        f"{TALKER}GGA,{_time(_utc(fix))},{lat},{ns},{lon},{ew},{fix.quality:d},{fix.num_sats:02d},"
        f"{_num(fix.hdop, '.2f')},{alt},M,{'0.0' if alt else ''},M,{age},{station}"
    )
    return sentence(body)


def rmc(fix: Fix) -> str:
    """Recommended minimum: time, status, position, speed over ground (knots), course, date, mode."""
    when = _utc(fix)
    valid = fix.quality != 0
    lat, ns = _angle(fix.lat if valid else math.nan, 2, "NS")
    lon, ew = _angle(fix.lon if valid else math.nan, 3, "EW")
    speed = _num(fix.speed_mps / KNOT_MPS if valid else math.nan, ".3f")
    course = _num(fix.course_deg if valid else math.nan, ".2f")
    mode = {0: "N", 1: "A", 6: "E"}.get(fix.quality, "A")
    body = f"{TALKER}RMC,{_time(when)},{'A' if valid else 'V'},{lat},{ns},{lon},{ew},{speed},{course},{when:%d%m%y},,,{mode}"
    return sentence(body)


def gsa(fix: Fix) -> str:
    """DOP and the satellites used (at most 12 listed); fix type 3 when a 3-D solution was computed."""
    used = [s.prn for s in fix.sats if s.used][:MAX_GSA_PRNS]
    fix_type = 3 if math.isfinite(fix.pdop) and used else 1
    prns = [f"{p:02d}" for p in used] + [""] * (MAX_GSA_PRNS - len(used))
    body = f"{TALKER}GSA,A,{fix_type},{','.join(prns)},{_num(fix.pdop, '.2f')},{_num(fix.hdop, '.2f')},{_num(fix.vdop, '.2f')}"
    return sentence(body)


def gsv(fix: Fix) -> list[str]:
    """Satellites in view, four per sentence: PRN, elevation, azimuth (deg), SNR (dB-Hz, empty if not tracked)."""
    sats = sorted(fix.sats, key=lambda s: s.prn)
    total = max(1, math.ceil(len(sats) / SATS_PER_GSV))
    out = []
    for index in range(total):
        chunk = sats[index * SATS_PER_GSV : (index + 1) * SATS_PER_GSV]
        fields = [f"{s.prn:02d},{round(s.el_deg):02d},{round(s.az_deg) % 360:03d},{'' if s.snr <= 0 else f'{round(s.snr):02d}'}" for s in chunk]
        out.append(sentence(",".join([f"{TALKER}GSV,{total},{index + 1},{len(sats):02d}", *fields])))
    return out


def fix_sentences(fix: Fix) -> list[str]:
    """All sentences of one epoch in the order receivers write them: GGA, RMC, GSA, GSV..."""
    return [gga(fix), rmc(fix), gsa(fix), *gsv(fix)]
