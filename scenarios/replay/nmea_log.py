"""An NMEA 0183 log (a receiver's serial output saved as text) read into time-ordered fixes.

Lines are read and cut into epochs by sim.nmea (scenarios.replay.fixes for the fix of each); blank
lines and '#' comments are passed over; every other line that is not read is counted (Tally) and
the replay reports the count. The log's clock is built from its valid fixes only: a receiver that
has no fix yet reports whatever its clock holds (the MTK-3301 of gpsd's mtk-3301.log writes
1980-01-05, the GPS epoch, until its first fix in 2008), so every epoch before the first one with a
fix and a time of day is set aside and counted, never stamped. From there each epoch is stamped with
its own UTC time: its time of day on its date (RMC's, else ZDA's); an epoch without a date takes the
latest date before it (the first date from the first fix on, before it appears), a day later when
its time of day falls more than 12 h below the previous epoch's (midnight passed); a log without any
date takes the scenario's UTC epoch's date. An epoch with no time at all (a receiver without a fix
may leave it empty) takes the stamp of the epoch before it. An epoch that jumps more than a day from
the one before it, back or forward (a receiver reset to its default date), is set aside and counted,
and its date is not carried; one stamped less than a day before the one before it (a receiver
restart) is left out and counted as out of time order.

A file is an NMEA log when its name ends in .nmea, or when it is a plain file (not a bag) whose
first lines hold a sentence. Alone it is a GNSS-only recording; attached to a capture or a bag
(`--nmea`) its fixes replace the recording's own GPS, in the recording's time base.
"""

from __future__ import annotations

import dataclasses
import heapq
import itertools
import math
import re
from collections.abc import Iterator
from datetime import date, datetime, timedelta
from pathlib import Path

from scenarios.replay import fixes
from scenarios.replay.recording import Event, Geo, LogStats, Place, RecordedFix, Recording, unix_ns
from sim.nmea.epochs import HALF_DAY_S, Epoch, Splitter, Tally, assemble

SUFFIXES = (".nmea", ".nmea0183")
BAG_SUFFIXES = (".bag", ".mcap", ".db3")
SNIFF_BYTES = 65_536
DAY_NS = 86_400 * 10**9
"""A stamp this far from the one before it is a receiver's clock reset, not time passing (module docstring)."""
_SENTENCE = re.compile(rb"^\s*\$[A-Z]{2}[A-Z0-9]{3},", re.MULTILINE)


def is_log(path: Path) -> bool:
    """Whether `path` is read as an NMEA log (module docstring)."""
    if path.suffix.lower() in SUFFIXES:
        return True
    if not path.is_file() or path.suffix.lower() in BAG_SUFFIXES:
        return False
    with path.open("rb") as handle:
        return bool(_SENTENCE.search(handle.read(SNIFF_BYTES)))


class Clock:
    """UTC of each epoch in log order (module docstring): the date carried from epoch to epoch."""

    def __init__(self, first_date: date) -> None:
        self.day = first_date
        self.previous: float | None = None
        self._pending = first_date

    def utc(self, epoch: Epoch) -> datetime | None:
        """The epoch's UTC time (None when it has no time of day); keep() carries its date on."""
        self._pending = self.day
        if epoch.date is not None:
            self._pending = epoch.date
        elif epoch.seconds_of_day is not None and self.previous is not None and epoch.seconds_of_day < self.previous - HALF_DAY_S:
            self._pending += timedelta(days=1)
        return epoch.utc(self._pending)

    def keep(self, epoch: Epoch) -> None:
        """Carry the date and time of day of the epoch last given to utc() on (it was kept; one set aside leaves both)."""
        if epoch.seconds_of_day is not None:
            self.day, self.previous = self._pending, epoch.seconds_of_day


def epochs(path: Path, tally: Tally) -> Iterator[Epoch]:
    """The log's epochs in order, its unread lines counted in `tally`."""
    splitter = Splitter(tally)
    with path.open("rb") as handle:
        for number, raw in enumerate(handle):
            closed = splitter.add(number, raw.decode("latin-1"))
            if closed:
                yield assemble(closed)
    last = splitter.close()
    if last:
        yield assemble(last)


def stamped(path: Path, default_date: date, stats: LogStats) -> Iterator[tuple[int, Epoch]]:
    """(UTC ns, epoch) of every epoch kept (module docstring), counting into `stats`."""
    timed_fix = [e.has_fix and e.seconds_of_day is not None for e in epochs(path, Tally())]
    start = timed_fix.index(True) if True in timed_fix else len(timed_fix)
    first_date = next((e.date for e in itertools.islice(epochs(path, Tally()), start, None) if e.date is not None), default_date)
    clock, last = Clock(first_date), None
    for index, epoch in enumerate(epochs(path, stats.tally)):
        stats.epochs += 1
        if index < start:
            stats.before_first_fix += 1
            continue
        when = clock.utc(epoch)
        ns = unix_ns(when) if when is not None else last
        assert ns is not None, "the first kept epoch has a time"
        if last is not None and abs(ns - last) > DAY_NS:
            stats.clock_jumps += 1
            continue
        if last is not None and ns < last:
            stats.out_of_order += 1
            continue
        clock.keep(epoch)
        last = ns
        stats.with_fix += epoch.has_fix
        yield ns, epoch


def fix_events(path: Path, geo: Geo, default_date: date, stats: LogStats) -> Iterator[RecordedFix]:
    """Every kept epoch as a RecordedFix in the replay's time base."""
    for ns, epoch in stamped(path, default_date, stats):
        stamp = geo.seconds(ns)
        fix = fixes.from_epoch(stamp, epoch, geo)
        if fix is not None:
            yield RecordedFix(stamp, fix, epoch.lines)


def span(path: Path, default_date: date, height: float) -> tuple[int, int, tuple[float, float, float], LogStats]:
    """(first and last stamp in UTC ns, the first fix's lat, lon, height (`height` without one), the counts) of a log;
    ValueError (one line) without a usable epoch (one with a time and a position)."""
    stats, first, last, position = LogStats(), None, None, None
    for ns, epoch in stamped(path, default_date, stats):
        first = ns if first is None else first
        last = ns
        if position is None and epoch.has_fix:
            position = (epoch.lat, epoch.lon, epoch.alt if math.isfinite(epoch.alt) else height)
    if first is None or last is None or position is None:
        raise ValueError(f"{path}: no usable NMEA epoch (none with a time and a position): {stats.summary()}")
    return first, last, position, stats


def read(path: str | Path, place: Place) -> Recording:
    """Open an NMEA log for a GNSS-only replay; ValueError (one line) when it cannot be read or holds no usable epoch."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such NMEA log")
    default_date = place.epoch_utc.date()
    first, last, position, stats = span(path, default_date, place.origin[2])
    geo = Geo.choose(place, first, position)
    counted = LogStats()
    return Recording(
        path,
        "NMEA log",
        "",
        f"NMEA sentences ({stats.epochs} epochs, {stats.with_fix} with a fix)",
        geo,
        geo.seconds(first),
        geo.seconds(last),
        events=lambda: fix_events(path, geo, default_date, counted),
        nmea=counted,
    )


def attach(recording: Recording, path: str | Path, place: Place) -> Recording:
    """`recording`'s scans with the fixes of the NMEA log at `path` instead of its own GPS, in its time base; ValueError
    (one line) when the log cannot be read or does not overlap the recording in time."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such NMEA log")
    default_date = place.epoch_utc.date()
    first, last, _, stats = span(path, default_date, place.origin[2])
    geo = recording.geo
    start, end = geo.seconds(first), geo.seconds(last)
    if end < recording.t_start or start > recording.t_end:
        raise ValueError(
            f"{path}: the NMEA log spans {geo.utc(start):%Y-%m-%d %H:%M:%S} to {geo.utc(end):%H:%M:%S} UTC, the recording "
            f"{geo.utc(recording.t_start):%Y-%m-%d %H:%M:%S} to {geo.utc(recording.t_end):%H:%M:%S}: they do not overlap"
        )
    counted = LogStats()

    def merged() -> Iterator[Event]:
        scans = (e for e in recording.events() if not isinstance(e, RecordedFix))
        fixes_of_log = fix_events(path, geo, default_date, counted)
        return heapq.merge(scans, fixes_of_log, key=lambda e: (e.stamp, isinstance(e, RecordedFix)))

    source = f"NMEA log {path.name} ({stats.epochs} epochs, {stats.with_fix} with a fix)"
    return dataclasses.replace(recording, gps_source=source, events=merged, nmea=counted)
