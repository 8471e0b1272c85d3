"""sim.nmea.read on real receivers' logs (tests/data/nmea, see its NOTICE.md): every sentence pynmea2 reads (strict:
with a matching checksum; without one, as its default mode reads it, where NMEA 0183 allows none) is read, with the same
values; garbage and truncated lines are counted, never raised."""

from __future__ import annotations

import math
from datetime import date, time
from pathlib import Path

import pynmea2
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.nmea import checksum, systems
from sim.nmea.epochs import Splitter, Tally, assemble
from sim.nmea.read import CHECKSUM_MANDATORY, KINDS, MIN_FIELDS, REASONS, Skipped, has_checksum, kind, read

DATA = Path(__file__).parent / "data" / "nmea"
LOGS = sorted(DATA.rglob("*.log"))


def lines_of(path: Path) -> list[str]:
    """The log's lines as a receiver sent them (bytes read as Latin-1: binary stays one character per byte)."""
    return [raw.decode("latin-1").strip() for raw in path.read_bytes().splitlines()]


def seconds(t: time | None) -> float | None:
    return None if t is None else t.hour * 3600 + t.minute * 60 + t.second + t.microsecond * 1e-6


def number(text) -> float:
    """pynmea2's field (a string, or a value its type converted) as a float, NaN when empty or not a number."""
    try:
        return float(text)
    except (TypeError, ValueError):
        return math.nan


def same(a: float, b: float, tol: float = 1e-9) -> bool:
    return (math.isnan(a) and math.isnan(b)) or abs(a - b) <= tol


def position(msg) -> tuple[float, float] | None:
    """pynmea2's latitude and longitude where it reads a position (both fields and hemispheres given)."""
    if not (msg.lat and msg.lon and msg.lat_dir in "NS" and msg.lon_dir in "EW" and msg.lat_dir and msg.lon_dir):
        return None
    return msg.latitude, msg.longitude


def compare(msg, rec) -> list[str]:
    """Every field pynmea2 gives a value for that differs from ours (empty: they agree)."""
    out = []

    def check(name: str, theirs, ours, tol: float = 1e-9) -> None:
        if isinstance(ours, str | bool | date):
            ok = theirs == ours
        else:
            ok = same(number(theirs), math.nan if ours is None else float(ours), tol)
        if not ok:
            out.append(f"{name}: pynmea2 {theirs!r}, ours {ours!r}")

    name = type(msg).__name__
    if hasattr(msg, "timestamp") and isinstance(msg.timestamp, time):
        check("time", seconds(msg.timestamp), rec.seconds_of_day, 1.5e-6)  # pynmea2 truncates to the microsecond
    if name in ("GGA", "RMC", "GLL", "GNS"):
        where = position(msg)
        if where is not None:
            check("lat", where[0], rec.lat, 1e-12)
            check("lon", where[1], rec.lon, 1e-12)
    if name == "GGA":
        check("quality", msg.gps_qual, rec.quality)
        check("num_sats", msg.num_sats, rec.num_sats)
        check("hdop", msg.horizontal_dil, rec.hdop)
        check("altitude", msg.altitude, rec.alt_msl)
        check("geoid_sep", msg.geo_sep, rec.geoid_sep)
    elif name == "RMC":
        check("status", msg.status == "A", rec.valid)
        check("speed", number(msg.spd_over_grnd) * pynmea2_knot(), rec.speed_mps, 1e-9)
        check("course", msg.true_course, rec.course_deg)
        if isinstance(msg.datestamp, date):
            check("date", msg.datestamp, rec.date)
        check("mode", msg.mode_indicator or "", rec.mode)
    elif name == "GSA":
        if len(msg.data) in (17, 18):
            check("fix_type", msg.mode_fix_type, rec.fix_type)
            prns = [int(getattr(msg, f"sv_id{k:02d}")) for k in range(1, 13) if getattr(msg, f"sv_id{k:02d}")]
            check("prns", str(prns), str(rec.prns))
            for dop in ("pdop", "hdop", "vdop"):
                check(dop, getattr(msg, dop), getattr(rec, dop))
    elif name == "GSV":
        check("total", msg.num_messages, rec.total)
        check("index", msg.msg_num, rec.index)
        check("in_view", msg.num_sv_in_view, rec.in_view)
        # pynmea2 predates NMEA 4.10: the signal id after the last slot (4k + 1 fields after the header) is to it a satellite's number
        signal = len(msg.data) - 1 if (len(msg.data) - 3) % 4 == 1 else None
        if signal is not None:
            check("signal_id", int(msg.data[signal], 16) if msg.data[signal] else None, rec.signal_id)
        slots = [
            tuple(number(getattr(msg, f"{field}{k}")) for field in ("sv_prn_num_", "elevation_deg_", "azimuth_", "snr_"))
            for k in range(1, 5)
            if getattr(msg, f"sv_prn_num_{k}") and 3 + 4 * (k - 1) != signal
        ]
        ours = [(s.prn, *(math.nan if v is None else v for v in (s.el, s.az, s.snr))) for s in rec.sats]
        if len(slots) != len(ours) or not all(same(a, b) for x, y in zip(slots, ours) for a, b in zip(x, y)):
            out.append(f"satellites: pynmea2 {slots}, ours {ours}")
    elif name == "VTG":
        check("course", msg.true_track, rec.course_deg)
        check("course_mag", msg.mag_track, rec.course_mag_deg)
        if msg.spd_over_grnd_kts is not None:
            check("speed", number(msg.spd_over_grnd_kts) * pynmea2_knot(), rec.speed_mps, 1e-9)
        check("mode", msg.faa_mode or "", rec.mode)
    elif name == "GLL":
        check("status", msg.status == "A", rec.valid)
        check("mode", msg.faa_mode or "", rec.mode)
    elif name == "ZDA":
        if isinstance(msg.day, int) and isinstance(msg.month, int) and isinstance(msg.year, int):
            check("date", msg.datestamp, rec.date)
    elif name == "GNS":
        check("mode", msg.mode_indicator, rec.mode)
        check("num_sats", msg.num_sats, rec.num_sats)
        check("hdop", msg.hdop, rec.hdop)
        check("altitude", msg.altitude, rec.alt_msl)
        check("geoid_sep", msg.geo_sep, rec.geoid_sep)
    elif name == "GST":
        for theirs, ours in (("rms", "rms_m"), ("std_dev_major", "major_m"), ("std_dev_minor", "minor_m"), ("orientation", "orientation_deg")):
            check(theirs, getattr(msg, theirs), getattr(rec, ours))
        for theirs, ours in (("std_dev_latitude", "sd_lat_m"), ("std_dev_longitude", "sd_lon_m"), ("std_dev_altitude", "sd_alt_m")):
            check(theirs, getattr(msg, theirs), getattr(rec, ours))
    return out


def pynmea2_knot() -> float:
    """Metres per second in a knot (1852 m per hour)."""
    return 1852.0 / 3600.0


def pynmea2_reads(line: str):
    """pynmea2's reading of a line (None when it refuses it or it is not a talker sentence of a type we read): strict with
    a checksum; without one its default reading, where NMEA 0183 allows no checksum (not RMA, RMB, RMC) and the sentence
    has the fields of its type (a truncated line has fewer: pynmea2 would read it too, we do not)."""
    try:
        msg = pynmea2.parse(line, check=has_checksum(line))
    except pynmea2.ParseError:
        return None
    name = type(msg).__name__
    if not has_checksum(line) and (name in CHECKSUM_MANDATORY or len(msg.data) < MIN_FIELDS.get(name, 0)):
        return None
    return msg if name in KINDS else None


@pytest.mark.parametrize("path", LOGS, ids=[p.name for p in LOGS])
def test_every_sentence_pynmea2_reads_is_read_alike(path):
    compared = 0
    for line in lines_of(path):
        if not line or line.startswith("#"):
            continue
        msg = pynmea2_reads(line)
        try:
            rec = read(line)
        except Skipped as why:
            assert msg is None, f"pynmea2 reads what we skip ({why.reason}): {line!r}"
            continue
        assert msg is not None and type(msg).__name__ == kind(rec), f"we read what pynmea2 does not: {line!r}"
        assert msg.talker == rec.talker
        differences = compare(msg, rec)
        assert not differences, f"{line!r}: {differences}"
        compared += 1
    assert compared > 0


def test_the_logs_hold_what_the_parser_was_asked_to_read():
    """Talkers, kinds and quirks the issue names are all in the copied logs (the comparison above covers them)."""
    kinds, talkers = set(), set()
    for path in LOGS:
        for line in lines_of(path):
            try:
                rec = read(line)
            except Skipped:
                continue
            kinds.add(kind(rec))
            talkers.add(rec.talker)
    assert kinds == set(KINDS)
    assert {"GP", "GN", "GL", "GA", "GB", "BD"} <= talkers


def test_sentences_without_a_checksum_are_read_where_nmea_0183_allows_it():
    """gpsd's hp58534a.log (an HP 58534A timing receiver) writes no checksum at all: its GGA, ZDA, GSV and VTG are read and
    counted as such; an RMC without one (its checksum is mandatory) and a GGA cut short are not."""
    epochs, tally = epochs_of(DATA / "gpsd" / "hp58534a.log")
    assert tally.read == {"GGA": 2, "ZDA": 1, "GSV": 6, "VTG": 2} and tally.unchecked == 11 and "without a checksum" in tally.summary()
    assert [e.has_fix for e in epochs] == [True, True] and [e.seconds_of_day for e in epochs] == [80689.0, 80690.0]
    gga = "$GPGGA,222449,3349.0337,S,01843.9282,E,1,07,02.31,000115.4,M,0033.3,M,,"
    assert read(gga).lat == pytest.approx(-(33 + 49.0337 / 60), abs=1e-12)
    for line in ("$GPRMC,222449,A,3349.0337,S,01843.9282,E,0.0,318.0,251010,,", gga[:40]):
        with pytest.raises(Skipped) as why:
            read(line)
        assert why.value.reason == "no checksum"


def test_two_digit_years_pivot_as_posix():
    body = "GPRMC,120000,A,4807.038,N,01131.000,E,0.0,0.0,050180,,"
    assert read(f"${body}*{checksum(body)}").date == date(1980, 1, 5)
    body = body.replace("050180", "311268")
    assert read(f"${body}*{checksum(body)}").date == date(2068, 12, 31)
    body = body.replace("311268", "010169")
    assert read(f"${body}*{checksum(body)}").date == date(1969, 1, 1)


def test_proprietary_sentences_are_not_talker_sentences():
    [line] = [x for x in lines_of(DATA / "gpsd" / "quectel-eg25-g.log") if x.startswith("$PQGSV")][:1]
    with pytest.raises(Skipped) as why:
        read(line)
    assert why.value.reason == "proprietary"


def test_glonass_in_gpgsv_and_nmea410_system_ids():
    """A chartplotter's GPGSV lists GLONASS as 65-96; NMEA 4.10 GSAs name their system; u-blox numbers BeiDou 401-437."""
    assert systems.satellite("GP", 70) == (systems.GLONASS, 6)
    assert systems.satellite("GP", 12) == (systems.GPS, 12)
    assert systems.satellite("GP", 46) == (systems.SBAS, 133)
    assert systems.satellite("GN", 81, 2) == (systems.GLONASS, 17)
    assert systems.satellite("GN", 7, 3) == (systems.GALILEO, 7)
    assert systems.satellite("GN", 405) == (systems.BEIDOU, 5)
    assert systems.satellite("GA", 102) == (systems.GALILEO, 2)  # Quectel LC79D's Galileo numbering
    assert systems.signal(systems.GALILEO, 7) == "E1-BC" and systems.signal(systems.GPS, 6) == "L2C-L"
    assert systems.signal(systems.GLONASS, None) == "L1OF"


def epochs_of(path: Path) -> tuple[list, Tally]:
    splitter = Splitter()
    out = []
    for n, line in enumerate(lines_of(path)):
        closed = splitter.add(n, line)
        if closed:
            out.append(assemble(closed))
    last = splitter.close()
    if last:
        out.append(assemble(last))
    return out, splitter.tally


def test_multi_gnss_epochs_carry_every_constellation_and_several_gsa():
    epochs, tally = epochs_of(DATA / "gpsd" / "ublox-zed-f9p-nmea.log")
    assert tally.skipped["bad checksum"] == 0 and tally.read["GSA"] > 0
    full = [e for e in epochs if e.sats]
    assert full
    seen = {(s.system, s.signal) for e in full for s in e.sats}
    assert {(systems.GPS, "L1 C/A"), (systems.GPS, "L2C-L"), (systems.GLONASS, "L1OF"), (systems.GALILEO, "E1-BC"), (systems.BEIDOU, "B1I")} <= seen
    used = {s.system for e in full for s in e.sats if s.used}
    assert {systems.GPS, systems.GLONASS, systems.GALILEO, systems.BEIDOU} <= used


def test_one_epoch_per_fix_time_whatever_its_print():
    lines = []
    for t in ("130711", "130712"):
        for body in (f"GPGGA,{t},4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,", f"GPRMC,{t}.00,A,4807.038,N,01131.000,E,0.0,0.0,050180,,"):
            lines.append(f"${body}*{checksum(body)}")
    splitter = Splitter()
    closed = [c for c in (splitter.add(k, line) for k, line in enumerate(lines)) if c]
    assert [[x.tag for x in c] for c in closed] == [[0, 1]] and [x.tag for x in splitter.close()] == [2, 3]


def test_a_multiplexers_repeated_lines_cut_no_epoch():
    # the B&G chartplotter's log repeats VTG, ZDA and XTE lines; each repeat used to cut a position-less epoch off (157 epochs)
    epochs, tally = epochs_of(DATA / "gpsd" / "bundg_zeus_9.log")
    times = [e.seconds_of_day for e in epochs if e.seconds_of_day is not None]
    assert tally.skipped["repeated line"] > 0
    assert len(epochs) == len(times) == len(set(times)) and all(e.has_fix for e in epochs)


def test_no_fix_and_dgps_epochs_are_kept():
    epochs, _ = epochs_of(DATA / "gpsd" / "ublox-lea-5q.log")
    assert any(e.quality == 0 for e in epochs)
    epochs, _ = epochs_of(DATA / "gpsd" / "furuno_gl_ga.log")
    gns = [read(next(x for x in e.lines if x.startswith("$GNGNS"))) for e in epochs]
    assert epochs and all(e.quality == 2 and e.num_sats == g.num_sats > 0 for e, g in zip(epochs, gns))  # GGA says 00 satellites: GNS's


@settings(max_examples=300, deadline=None)
@given(
    st.lists(
        st.one_of(
            st.text(max_size=120),
            st.binary(max_size=120).map(lambda b: b.decode("latin-1")),
            st.sampled_from([line for path in LOGS[:8] for line in lines_of(path)[:40]]).flatmap(
                lambda line: st.integers(0, len(line)).map(lambda n: line[:n])
            ),
            st.builds(
                lambda kind, fields: f"$GP{kind},{','.join(fields)}",
                st.sampled_from(KINDS),
                st.lists(st.text(alphabet="0123456789.,-NSEWAV", max_size=12), max_size=25),
            ).map(lambda s: f"{s}*{checksum(s[1:])}"),
        ),
        max_size=30,
    )
)
def test_garbage_and_truncated_lines_never_raise_and_are_counted(lines):
    splitter = Splitter()
    for n, line in enumerate(lines):
        closed = splitter.add(n, line)
        if closed:
            assemble(closed)
    last = splitter.close()
    if last:
        assemble(last)
    tally = splitter.tally
    kept = [line for line in lines if line.strip() and not line.strip().startswith("#")]
    assert sum(tally.read.values()) + sum(tally.skipped.values()) == len(kept)
    assert set(tally.skipped) <= set(REASONS)
