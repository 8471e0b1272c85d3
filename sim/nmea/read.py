"""NMEA 0183 sentences as real receivers write them (v2.x to 4.11, any talker), read into typed records.

read(line) gives one record (Gga, Rmc, Gsa, Gsv, Vtg, Gll, Zda, Gns, Gst) or raises Skipped naming
why the line is not read:
- "not a sentence": no '$' address and body (garbage, a truncated or merged line, a comment);
- "bad checksum": a '*hh' that does not match the sentence;
- "no checksum": a sentence without '*hh' that cannot be read safely. NMEA 0183 made the checksum
  optional but for RMA, RMB and RMC (version 2.0, 1992; e.g. Leica's MK9 manual quotes it: "Checksum is
  mandatory in this sentence"), and receivers such as the HP/Symmetricom 58534A write none (gpsd's
  hp58534a.log). Such a sentence is read, as pynmea2 reads it (its default, non-strict mode), when its
  type allows it and it has at least the fields its type has had since NMEA 0183 2.0 (MIN_FIELDS): a line
  cut short by a truncated log loses fields, so it is still refused; only a cut inside the last field
  cannot be told. Sentences read without a checksum are counted (sim.nmea.epochs.Tally.unchecked);
- "proprietary": $P... sentences are a manufacturer's own ($PQGSV is Quectel's, $PUBX u-blox's),
  never read as talker sentences;
- "other type": a sentence of a type not read here (TXT, GBS, HDT, AIS !AIVDM, ...).
Fields are read leniently, as receivers leave them: an empty or unreadable field is absent (NaN
for measurements, None for times, dates, counts and ids) and the rest of the sentence is still
read; a short sentence reads its missing trailing fields as empty. Positions: (d)ddmm.mmmm with the
degrees before the minutes' two integer digits (as pynmea2 reads them), signed by the hemisphere
letter (none: no position). Dates: ddmmyy with two-digit years pivoted as POSIX strptime's %y
(POSIX.1-2017, strptime: 69-99 -> 1969-1999, 00-68 -> 2000-2068; pynmea2 reads them with it).
Times: hhmmss[.s...] as seconds of the UTC day.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from datetime import date
from typing import NamedTuple

from sim.nmea.write import KNOT_MPS, checksum

KMH_MPS = 1.0 / 3.6
REASONS = ("not a sentence", "no checksum", "bad checksum", "proprietary", "other type", "repeated line")
"""Why a line is not read (Skipped.reason; "repeated line": sim.nmea.epochs drops a line identical to one already in its epoch)."""
_TIME = re.compile(r"(\d\d)(\d\d)(\d\d(?:\.\d*)?)")
_DATE = re.compile(r"(\d\d)(\d\d)(\d\d)")
_ANGLE = re.compile(r"(\d+)(\d\d(?:\.\d*)?)")
_ADDRESS = re.compile(r"[A-Z0-9]{5}")
CHECKSUM_MANDATORY = ("RMA", "RMB", "RMC")
"""Sentence types whose checksum NMEA 0183 (from version 2.0) makes mandatory: never read without one."""
MIN_FIELDS = {"GGA": 14, "GSA": 17, "GSV": 3, "VTG": 8, "GLL": 6, "ZDA": 6, "GNS": 12, "GST": 8}
"""Data fields (after the address) each type has had since NMEA 0183 2.0 (GLL: 2.0's six, before 2.3's mode; VTG: eight
before 2.3's mode; GNS: 3.0's twelve; GSV: the header, each satellite's four more): a sentence without a checksum with
fewer was cut short."""


class Skipped(ValueError):
    """A line that is not read; `reason` is one of REASONS."""

    def __init__(self, reason: str, line: str) -> None:
        super().__init__(f"nmea: {reason}: {line[:90]!r}")
        self.reason = reason


class GsvSatellite(NamedTuple):
    """One satellite slot of a GSV: the number the receiver gives it, elevation and azimuth (deg), C/N0 (dB-Hz); None when empty."""

    prn: int
    el: float | None
    az: float | None
    snr: float | None


@dataclass(frozen=True)
class Gga:
    """Fix data. alt: ellipsoidal height (altitude above the geoid plus the geoid separation; the altitude alone without one)."""

    talker: str
    seconds_of_day: float | None
    lat: float
    lon: float
    quality: int | None
    num_sats: int | None
    hdop: float
    alt_msl: float
    geoid_sep: float
    alt: float
    age_s: float
    station: str


@dataclass(frozen=True)
class Rmc:
    """Recommended minimum: status (valid: 'A'), position, speed over ground and course, date, mode (NMEA 2.3), navigational status (4.10)."""

    talker: str
    seconds_of_day: float | None
    valid: bool
    lat: float
    lon: float
    speed_mps: float
    course_deg: float
    date: date | None
    mode: str
    nav_status: str


@dataclass(frozen=True)
class Gsa:
    """DOP and the satellites used; system_id: the NMEA 4.10 GNSS system id of the listed satellites (None before 4.10)."""

    talker: str
    mode: str
    fix_type: int | None
    prns: list[int]
    pdop: float
    hdop: float
    vdop: float
    system_id: int | None


@dataclass(frozen=True)
class Gsv:
    """Satellites in view, one sentence of a cycle; signal_id: the NMEA 4.10 signal id (None before 4.10)."""

    talker: str
    total: int | None
    index: int | None
    in_view: int | None
    sats: list[GsvSatellite]
    signal_id: int | None


@dataclass(frozen=True)
class Vtg:
    """Course over ground (true, magnetic) and speed over ground (from knots, else km/h), mode."""

    talker: str
    course_deg: float
    course_mag_deg: float
    speed_mps: float
    mode: str


@dataclass(frozen=True)
class Gll:
    """Geographic position, its time, status (valid: 'A') and mode."""

    talker: str
    lat: float
    lon: float
    seconds_of_day: float | None
    valid: bool
    mode: str


@dataclass(frozen=True)
class Zda:
    """Time and date (four-digit year) and the local zone."""

    talker: str
    seconds_of_day: float | None
    date: date | None
    zone_hours: int | None
    zone_minutes: int | None


@dataclass(frozen=True)
class Gns:
    """Fix data of a multi-GNSS receiver: mode one letter per system (GPS, GLONASS, Galileo, BeiDou, ...), satellites, HDOP, heights."""

    talker: str
    seconds_of_day: float | None
    lat: float
    lon: float
    mode: str
    num_sats: int | None
    hdop: float
    alt_msl: float
    geoid_sep: float
    alt: float
    age_s: float
    station: str
    nav_status: str


@dataclass(frozen=True)
class Gst:
    """Pseudorange error statistics: RMS of the range residuals, error ellipse and 1-sigma latitude, longitude and altitude errors (m)."""

    talker: str
    seconds_of_day: float | None
    rms_m: float
    major_m: float
    minor_m: float
    orientation_deg: float
    sd_lat_m: float
    sd_lon_m: float
    sd_alt_m: float


Record = Gga | Rmc | Gsa | Gsv | Vtg | Gll | Zda | Gns | Gst


def read(line: str) -> Record:
    """One sentence as its record; Skipped (a ValueError) with the reason it is not read."""
    text = line.strip()
    if text.startswith("!"):
        raise Skipped("other type", text)
    if not text.startswith("$") or "," not in text:
        raise Skipped("not a sentence", text)
    checked = has_checksum(text)
    body = text[1 : text.rfind("*")] if checked else text[1:]
    if checked and text[text.rfind("*") + 1 :].upper() != checksum(body):
        raise Skipped("bad checksum", f"{text} (computed {checksum(body)})")
    address, *fields = body.split(",")
    if address.startswith("P"):
        raise Skipped("proprietary", text)
    if not _ADDRESS.fullmatch(address):
        raise Skipped("not a sentence", text)
    decoder = _DECODERS.get(address[2:])
    if not checked and (address[2:] in CHECKSUM_MANDATORY or len(fields) < MIN_FIELDS.get(address[2:], 0)):
        raise Skipped("no checksum", text)
    if decoder is None:
        raise Skipped("other type", text)
    return decoder(address[:2], _Fields(fields))


def has_checksum(line: str) -> bool:
    """Whether a sentence carries a '*hh' checksum field (module docstring: one without it may still be read)."""
    return "*" in line


def parse(line: str) -> dict:
    """One sentence as a dict ('type' and its record's fields); ValueError (Skipped) when it is not read."""
    record = read(line)
    return {"type": kind(record), **{f.name: getattr(record, f.name) for f in dataclasses.fields(record)}}


def kind(record: Record) -> str:
    """The sentence type of a record ('GGA', 'RMC', ...)."""
    return type(record).__name__.upper()


class _Fields:
    """A sentence's data fields by index, '' past its end."""

    def __init__(self, fields: list[str]) -> None:
        self.fields = [f.strip() for f in fields]

    def __getitem__(self, index: int) -> str:
        return self.fields[index] if index < len(self.fields) else ""

    def __len__(self) -> int:
        return len(self.fields)

    def number(self, index: int) -> float:
        """A finite float, else NaN."""
        try:
            value = float(self[index])
        except ValueError:
            return math.nan
        return value if math.isfinite(value) else math.nan

    def integer(self, index: int) -> int | None:
        """A decimal integer, else None."""
        text = self[index]
        return int(text) if text.isdigit() else None

    def time(self, index: int) -> float | None:
        """hhmmss[.s...] as seconds of the day, else None."""
        match = _TIME.fullmatch(self[index])
        if not match:
            return None
        hours, minutes, seconds = int(match[1]), int(match[2]), float(match[3])
        return hours * 3600 + minutes * 60 + seconds if hours < 24 and minutes < 60 and seconds < 61 else None

    def date(self, index: int) -> date | None:
        """ddmmyy (POSIX %y pivot), else None."""
        match = _DATE.fullmatch(self[index])
        if not match:
            return None
        yy = int(match[3])
        try:
            return date(yy + (1900 if yy >= 69 else 2000), int(match[2]), int(match[1]))
        except ValueError:
            return None

    def angle(self, index: int) -> float:
        """(d)ddmm.mmmm signed by the hemisphere letter in the next field, else NaN."""
        match = _ANGLE.fullmatch(self[index])
        sign = {"N": 1.0, "E": 1.0, "S": -1.0, "W": -1.0}.get(self[index + 1])
        if not match or sign is None:
            return math.nan
        return sign * (int(match[1]) + float(match[2]) / 60.0)

    def hex_id(self, index: int) -> int | None:
        """A one-digit hexadecimal id (NMEA 4.10 signal and system ids), else None."""
        text = self[index]
        return int(text, 16) if len(text) == 1 and text in "0123456789ABCDEFabcdef" else None


def _ellipsoidal(msl: float, separation: float) -> float:
    return msl + separation if math.isfinite(separation) else msl


def _gga(talker: str, f: _Fields) -> Gga:
    msl, sep = f.number(8), f.number(10)
    return Gga(
        talker, f.time(0), f.angle(1), f.angle(3), f.integer(5), f.integer(6), f.number(7), msl, sep, _ellipsoidal(msl, sep), f.number(12), f[13]
    )


def _rmc(talker: str, f: _Fields) -> Rmc:
    return Rmc(talker, f.time(0), f[1] == "A", f.angle(2), f.angle(4), f.number(6) * KNOT_MPS, f.number(7), f.date(8), f[11], f[12])


def _gsa(talker: str, f: _Fields) -> Gsa:
    """12 satellite fields (some receivers write more); NMEA 4.10 adds the system id after the DOPs (18 fields in all)."""
    system = f.hex_id(17) if len(f) == 18 else None
    end = 17 if len(f) == 18 else max(len(f), 17)
    prns = [p for p in (f.integer(i) for i in range(2, end - 3)) if p]
    return Gsa(talker, f[0], f.integer(1), prns, f.number(end - 3), f.number(end - 2), f.number(end - 1), system)


def _gsv(talker: str, f: _Fields) -> Gsv:
    """Up to four satellites of four fields each after three header fields; one more field is the NMEA 4.10 signal id. Empty slots
    (padding) are left out; a slot's empty elevation, azimuth or C/N0 is None."""
    slots = len(f) - 3
    signal = f.hex_id(len(f) - 1) if slots > 0 and slots % 4 == 1 else None
    sats = []
    for i in range(3, 3 + slots - slots % 4, 4):
        prn = f.integer(i)
        if prn:
            sats.append(GsvSatellite(prn, *(_optional(f.number(i + k)) for k in (1, 2, 3))))
    return Gsv(talker, f.integer(0), f.integer(1), f.integer(2), sats, signal)


def _optional(value: float) -> float | None:
    return None if math.isnan(value) else value


def _vtg(talker: str, f: _Fields) -> Vtg:
    knots, kmh = f.number(4), f.number(6)
    return Vtg(talker, f.number(0), f.number(2), knots * KNOT_MPS if math.isfinite(knots) else kmh * KMH_MPS, f[8])


def _gll(talker: str, f: _Fields) -> Gll:
    return Gll(talker, f.angle(0), f.angle(2), f.time(4), f[5] == "A", f[6])


def _zda(talker: str, f: _Fields) -> Zda:
    day, month, year = f.integer(1), f.integer(2), f.integer(3)
    try:
        when = date(year, month, day) if day and month and year else None
    except ValueError:
        when = None
    return Zda(talker, f.time(0), when, _signed(f[4]), _signed(f[5]))


def _signed(text: str) -> int | None:
    try:
        return int(text)
    except ValueError:
        return None


def _gns(talker: str, f: _Fields) -> Gns:
    msl, sep = f.number(8), f.number(9)
    return Gns(
        talker, f.time(0), f.angle(1), f.angle(3), f[5], f.integer(6), f.number(7), msl, sep, _ellipsoidal(msl, sep), f.number(10), f[11], f[12]
    )


def _gst(talker: str, f: _Fields) -> Gst:
    return Gst(talker, f.time(0), *(f.number(i) for i in range(1, 8)))


_DECODERS: dict[str, Callable[[str, _Fields], Record]] = {
    "GGA": _gga,
    "RMC": _rmc,
    "GSA": _gsa,
    "GSV": _gsv,
    "VTG": _vtg,
    "GLL": _gll,
    "ZDA": _zda,
    "GNS": _gns,
    "GST": _gst,
}
KINDS = tuple(_DECODERS)
"""The sentence types read."""
