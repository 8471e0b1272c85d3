"""A receiver's NMEA stream cut into epochs, each merged into one Epoch; what was not read, counted.

Cutting (Splitter): an epoch is the run of sentences from one fix time to the next. A GGA, RMC or
GNS closes the open epoch when its time differs in value from the epoch's (GGA '130711' and RMC
'130711.00' are one epoch; compared to the millisecond; a receiver that writes one GGA and RMC per
system, GPGGA then GAGGA, writes them with one time). When either has no time, a second sentence
of a type a receiver writes once per epoch (GGA, RMC, GNS, GLL, VTG, ZDA, GST) from the same talker
(GPVTG and GAVTG are one epoch's) closes it: this
cuts the epochs of a receiver that leaves its time empty while it has no fix, and a GLL, whose
time never cuts (receivers stamp it a few milliseconds or a second off their GGA's), joins the
epoch it follows. Every other line (GSA, GSV, unread lines) joins the open epoch. A line identical to one already in the
open epoch is a repeat, as an NMEA multiplexer writes them (gpsd's bundg_zeus_9.log, a B&G chartplotter's, repeats
VTG, ZDA, XTE lines): it is dropped, counted as "repeated line", and cuts nothing (a repeated VTG would otherwise cut
a position-less epoch off the fix's). Lines that are not read are counted by reason (sim.nmea.read.REASONS) in a Tally.

Merging (assemble), each value from the first sentence that gives it:
- time: GGA, RMC, GNS, else GLL, else ZDA (of several GGAs, RMCs or GNSs: the GN talker's, else
  the first); date: RMC, else ZDA (a day later or earlier when ZDA's time
  of day is more than 12 h from the epoch's: it straddles midnight);
- position and height: GGA, else GNS, else RMC, else GLL (latitude beyond +-90 deg or longitude
  beyond +-180 deg: none);
- quality, as GGA's indicator (0 no fix, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, 6 dead
  reckoning): GGA's, else from GNS's mode letters (the best of its systems: R 4, F 5, D 2, A/P 1,
  E 6, N 0), else RMC's or GLL's (mode E: 6; mode N or status not 'A': 0; else mode D 2, R 4, F
  5, others 1), else 0; an epoch with no position has quality 0;
- satellites used: GNS's count (it counts every system), else GGA's, else (none or 0 with a fix)
  the GSAs' satellites; HDOP GGA's, else GNS's, else GSA's; PDOP and VDOP from the GSAs;
- speed and course: RMC, else VTG;
- satellites: every GSV slot, by (system, svid, signal) (sim.nmea.systems; the last report of
  one wins), used when a GSA of the epoch lists it (by the NMEA 4.10 system id, the talker, else
  the number's range).
"""

from __future__ import annotations

import math
from collections import Counter
from dataclasses import dataclass, field
from datetime import UTC, date, datetime, timedelta
from typing import Protocol, TypeVar

from sim.nmea import systems
from sim.nmea.read import Gga, Gll, Gns, Gsa, Gsv, Record, Rmc, Skipped, Vtg, Zda, has_checksum, kind, read

TIMED = ("GGA", "RMC", "GNS")
"""Sentences whose fix time cuts epochs."""
POSITIONS = (*TIMED, "GLL")
"""Sentences that give a position (an epoch with none of them is no fix)."""
ONCE = (*POSITIONS, "VTG", "ZDA", "GST")
"""Sentences a receiver writes at most once per epoch."""
HALF_DAY_S = 43_200.0
Day = date
"""A calendar date (Epoch has a field named date)."""
GNS_QUALITY = {"R": 4, "F": 5, "D": 2, "A": 1, "P": 1, "E": 6, "N": 0}
"""GNS mode letter -> GGA quality, best first."""


@dataclass
class Tally:
    """Lines read (by sentence type; how many of them without a checksum, as NMEA 0183 allows: sim.nmea.read) and not read
    (by reason) so far."""

    read: Counter[str] = field(default_factory=Counter)
    skipped: Counter[str] = field(default_factory=Counter)
    unchecked: int = 0

    def summary(self) -> str:
        """One line: how many sentences were read (and of them without a checksum) and how many lines skipped, by reason."""
        read = ", ".join(f"{k} {n}" for k, n in sorted(self.read.items()))
        skipped = ", ".join(f"{n} {reason}" for reason, n in self.skipped.most_common())
        unchecked = f", {self.unchecked} of them without a checksum" if self.unchecked else ""
        return f"read {sum(self.read.values())} sentences ({read or 'none'}){unchecked}; skipped {sum(self.skipped.values())} lines" + (
            f" ({skipped})" if skipped else ""
        )


@dataclass(frozen=True)
class Line:
    """One line of the stream: the caller's tag (e.g. its log time), the text, and its record (None when it was not read)."""

    tag: int
    text: str
    record: Record | None


class Splitter:
    """Cut a stream of lines into epochs (module docstring): add() returns the epoch a line closed, if any."""

    def __init__(self, tally: Tally | None = None) -> None:
        self.tally = tally if tally is not None else Tally()
        self._lines: list[Line] = []
        self._time: float | None = None
        self._kinds: set[tuple[str, str]] = set()  # (sentence type, talker) read in the open epoch

    @property
    def open_tag(self) -> int | None:
        """The tag of the open epoch's first line (None when none is open)."""
        return self._lines[0].tag if self._lines else None

    def add(self, tag: int, text: str) -> list[Line] | None:
        """Take one line; a line that starts a new epoch returns the one it closed."""
        text = text.strip()
        if not text or text.startswith("#"):
            return None
        if any(line.text == text for line in self._lines):
            self.tally.skipped["repeated line"] += 1
            return None
        try:
            record: Record | None = read(text)
        except Skipped as why:
            self.tally.skipped[why.reason] += 1
            record = None
        name = kind(record) if record is not None else ""
        if record is not None:
            self.tally.read[name] += 1
            self.tally.unchecked += not has_checksum(text)
        time = getattr(record, "seconds_of_day", None) if name in TIMED else None
        key = None if time is None else round(time * 1000)
        talker = record.talker if record is not None else ""
        if key is not None and self._time is not None:
            cut = key != self._time
        else:
            cut = name in ONCE and (name, talker) in self._kinds
        closed = self.close() if cut else None
        self._lines.append(Line(tag, text, record))
        self._kinds.add((name, talker))
        self._time = key if self._time is None else self._time
        return closed

    def close(self) -> list[Line] | None:
        """The open epoch's lines (and none is open after), or None."""
        if not self._lines:
            return None
        lines, self._lines, self._time, self._kinds = self._lines, [], None, set()
        return lines


@dataclass(frozen=True)
class Satellite:
    """One satellite signal as the receiver reports it: its system, number in it (svid) and in the receiver's
    numbering, elevation and azimuth (deg, NaN when empty), C/N0 (dB-Hz, NaN when not tracked), signal, used in the fix."""

    system: str
    svid: int
    number: int
    el_deg: float
    az_deg: float
    snr: float
    signal: str
    used: bool


@dataclass(frozen=True)
class Epoch:
    """One receiver epoch merged from its sentences (module docstring); NaN or None where the receiver gave nothing."""

    seconds_of_day: float | None
    date: date | None
    lat: float
    lon: float
    alt: float
    quality: int
    num_sats: int
    hdop: float
    vdop: float
    pdop: float
    speed_mps: float
    course_deg: float
    sats: tuple[Satellite, ...]
    lines: tuple[str, ...]
    kinds: frozenset[str]
    """The sentence types read in the epoch."""

    @property
    def has_fix(self) -> bool:
        """A measured or dead-reckoned position (quality not 0)."""
        return self.quality != 0

    def utc(self, day: Day) -> datetime | None:
        """The epoch's UTC time on `day` (None without a time of day)."""
        if self.seconds_of_day is None:
            return None
        return datetime(day.year, day.month, day.day, tzinfo=UTC) + timedelta(seconds=self.seconds_of_day)


def assemble(lines: list[Line]) -> Epoch:
    """Merge one epoch's lines into an Epoch (module docstring)."""
    records = [line.record for line in lines if line.record is not None]
    gga = _preferred([r for r in records if isinstance(r, Gga)])
    gns = _preferred([r for r in records if isinstance(r, Gns)])
    rmc = _preferred([r for r in records if isinstance(r, Rmc)])
    gll = _preferred([r for r in records if isinstance(r, Gll)])
    vtg = _preferred([r for r in records if isinstance(r, Vtg)])
    zda = _preferred([r for r in records if isinstance(r, Zda)])
    gsas = [r for r in records if isinstance(r, Gsa)]
    timed = [r for r in (gga, rmc, gns, gll) if r is not None and r.seconds_of_day is not None]
    seconds = timed[0].seconds_of_day if timed else zda.seconds_of_day if zda is not None else None
    source = next((r for r in (gga, gns, rmc, gll) if r is not None and _on_earth(r.lat, r.lon)), None)
    lat, lon = (source.lat, source.lon) if source is not None else (math.nan, math.nan)
    alt = source.alt if isinstance(source, Gga | Gns) else math.nan
    quality = _quality(gga, gns, rmc, gll) if source is not None else 0
    used = {systems.satellite(g.talker, prn, g.system_id) for g in gsas for prn in g.prns}
    count = next((r.num_sats for r in (gns, gga) if r is not None and r.num_sats is not None), None)
    if not count and quality:
        count = len(used)
    return Epoch(
        seconds_of_day=seconds,
        date=_date(rmc, zda, seconds),
        lat=lat,
        lon=lon,
        alt=alt,
        quality=quality,
        num_sats=count or 0,
        hdop=_first(*(r.hdop for r in (gga, gns) if r is not None), *(g.hdop for g in gsas)),
        vdop=_first(*(g.vdop for g in gsas)),
        pdop=_first(*(g.pdop for g in gsas)),
        speed_mps=_first(*(r.speed_mps for r in (rmc, vtg) if r is not None)),
        course_deg=_first(*(r.course_deg for r in (rmc, vtg) if r is not None)),
        sats=_satellites([r for r in records if isinstance(r, Gsv)], used),
        lines=tuple(line.text for line in lines),
        kinds=frozenset(kind(r) for r in records),
    )


class _Talked(Protocol):
    @property
    def talker(self) -> str: ...


T = TypeVar("T", bound=_Talked)


def _preferred(records: list[T]) -> T | None:
    """Of several sentences of one type in an epoch, the GN (combined) talker's, else the first; None when there is none."""
    return next((r for r in records if r.talker == "GN"), records[0] if records else None)


def _on_earth(lat: float, lon: float) -> bool:
    return abs(lat) <= 90.0 and abs(lon) <= 180.0  # False for NaN


def _first(*values: float) -> float:
    """The first finite value, else NaN."""
    return next((v for v in values if math.isfinite(v)), math.nan)


def _quality(gga: Gga | None, gns: Gns | None, rmc: Rmc | None, gll: Gll | None) -> int:
    """GGA's quality indicator, else the one GNS's, RMC's or GLL's mode and status imply (module docstring)."""
    if gga is not None and gga.quality is not None:
        return gga.quality
    if gns is not None and gns.mode:
        return next((q for letter, q in GNS_QUALITY.items() if letter in gns.mode), 0)
    for status in (rmc, gll):
        if status is not None:
            if status.mode == "E":
                return 6
            if status.mode == "N" or not status.valid:
                return 0
            return {"D": 2, "R": 4, "F": 5}.get(status.mode, 1)
    return 0


def _date(rmc: Rmc | None, zda: Zda | None, seconds: float | None) -> date | None:
    """RMC's date, else ZDA's moved by a day when ZDA's time of day is on the other side of midnight from the epoch's."""
    if rmc is not None and rmc.date is not None:
        return rmc.date
    if zda is None or zda.date is None:
        return None
    if seconds is None or zda.seconds_of_day is None:
        return zda.date
    gap = zda.seconds_of_day - seconds
    return zda.date + timedelta(days=1 if gap < -HALF_DAY_S else -1 if gap > HALF_DAY_S else 0)


def _satellites(gsvs: list[Gsv], used: set[tuple[str, int]]) -> tuple[Satellite, ...]:
    """Every GSV slot as a Satellite, the last report of a (system, svid, signal) kept, in order of first report."""
    out: dict[tuple[str, int, str], Satellite] = {}
    for gsv in gsvs:
        for slot in gsv.sats:
            system, svid = systems.satellite(gsv.talker, slot.prn)
            signal = systems.signal(system, gsv.signal_id)
            out[(system, svid, signal)] = Satellite(
                system,
                svid,
                slot.prn,
                math.nan if slot.el is None else slot.el,
                math.nan if slot.az is None else slot.az,
                math.nan if slot.snr is None else slot.snr,
                signal,
                (system, svid) in used,
            )
    return tuple(out.values())
