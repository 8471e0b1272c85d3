"""NMEA 0183 output: checksums, field formats, and a round trip through the reader (sim.nmea.read, sim.nmea.epochs)."""

from __future__ import annotations

import math
from datetime import UTC, datetime, timedelta

import gnss_worlds as gw
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim import nmea
from sim.gnss import GnssReceiver
from sim.gnss_fix import GnssFix, SatelliteReport
from sim.nmea.epochs import Epoch, Line, assemble
from sim.nmea.read import Gsa, Gsv, Rmc, read


def test_checksum_of_the_classic_example():
    # The GGA example of the NMEA 0183 documentation, checksum *47.
    assert nmea.checksum("GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,") == "47"
    parsed = nmea.parse("$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47")
    assert parsed["lat"] == pytest.approx(48 + 7.038 / 60) and parsed["lon"] == pytest.approx(11 + 31.0 / 60)
    assert parsed["alt"] == pytest.approx(545.4 + 46.9) and parsed["quality"] == 1 and parsed["num_sats"] == 8


def test_parser_rejects_bad_checksums_and_garbage():
    line = nmea.sentence("GPGSA,A,3,04,05,,,,,,,,,,,2.50,1.30,2.10")
    nmea.parse(line)
    with pytest.raises(ValueError, match="checksum"):
        nmea.parse(line[:-2] + ("00" if line[-2:] != "00" else "01"))
    with pytest.raises(ValueError, match="checksum"):
        nmea.parse(line.replace("2.50", "2.51"))
    with pytest.raises(ValueError, match="not a sentence"):
        nmea.parse("GPGGA,no dollar")


def test_receiver_epoch_sentences_are_valid_and_parse_back():
    rx = GnssReceiver(profile="consumer", seed=2)
    world, motion = gw.open_water(), gw.Straight(speed=2.0, y=3.0)
    for t in rx.epochs(3.0):
        fix = rx.fix(world, motion, t)
    lines = fix.nmea()
    kinds = [line[3:6] for line in lines]
    assert kinds[:2] == ["GGA", "RMC"] and kinds == ["GGA", "RMC"] + ["GSA"] * 4 + ["GSV"] * (len(lines) - 6)
    for line in lines:
        body, cs = line[1:].split("*")
        assert cs == nmea.checksum(body) and len(line) <= 82
    back = epoch(lines)
    assert back.lat == pytest.approx(fix.lat, abs=1e-7) and back.lon == pytest.approx(fix.lon, abs=1e-7)
    assert back.quality == 1 and back.num_sats == fix.num_sats
    assert back.speed_mps == pytest.approx(fix.speed_mps, abs=1e-3)
    assert back.utc(back.date) == datetime.fromisoformat(fix.utc)


def epoch(lines: list[str]) -> Epoch:
    """One epoch's sentences read and merged."""
    return assemble([Line(k, line, read(line)) for k, line in enumerate(lines)])


def _fix(lat, lon, alt, when, quality, sats, hdop, speed, course) -> GnssFix:
    valid = quality != 0
    used = sum(s.used for s in sats)
    return GnssFix(
        stamp=0.0,
        lat=lat if valid else math.nan,
        lon=lon if valid else math.nan,
        alt=alt if valid else math.nan,
        enu=np.zeros(3),
        quality=quality,
        num_sats=used,
        hdop=hdop if used >= 4 else math.nan,
        vdop=1.5 * hdop if used >= 4 else math.nan,
        pdop=1.8 * hdop if used >= 4 else math.nan,
        sats=tuple(sats),
        utc=when.isoformat(),
        speed_mps=speed,
        course_deg=course,
    )


satellites = st.lists(
    st.builds(
        SatelliteReport,
        prn=st.integers(1, 32),
        az_deg=st.floats(0.0, 359.4),
        el_deg=st.floats(0.0, 90.0),
        snr=st.one_of(st.just(0.0), st.floats(20.0, 55.0)),
        used=st.booleans(),
    ),
    max_size=16,
    unique_by=lambda s: s.prn,
)


@settings(max_examples=200, deadline=None)
@given(
    lat=st.floats(-89.999, 89.999),
    lon=st.floats(-179.999, 179.999),
    alt=st.floats(-100.0, 5000.0),
    seconds=st.floats(0.0, 86400.0 * 365),
    quality=st.sampled_from([0, 1, 6]),
    sats=satellites,
    hdop=st.floats(0.5, 30.0),
    speed=st.floats(0.0, 20.0),
    course=st.floats(0.0, 359.99),
)
def test_round_trip_over_positions_times_and_satellites(lat, lon, alt, seconds, quality, sats, hdop, speed, course):
    when = datetime(2024, 1, 1, tzinfo=UTC) + timedelta(seconds=seconds)
    fix = _fix(lat, lon, alt, when, quality, sats, hdop, speed, course)
    lines = fix.nmea()
    back = epoch(lines)
    rmc, gsa, gsvs = read(lines[1]), read(lines[2]), [read(line) for line in lines[3:]]
    assert isinstance(rmc, Rmc) and isinstance(gsa, Gsa) and all(isinstance(g, Gsv) for g in gsvs)
    assert abs(back.utc(back.date) - when) <= timedelta(milliseconds=5)
    assert back.quality == quality and back.num_sats == fix.num_sats
    if quality:
        tol = 0.5e-5 / 60 + 1e-12  # 5 decimals of arc minutes
        assert abs(back.lat - lat) <= tol and abs(back.lon - lon) <= tol
        assert back.alt == pytest.approx(alt, abs=0.005 + 1e-9)
        assert back.speed_mps == pytest.approx(speed, abs=0.0005 * nmea.KNOT_MPS + 1e-9)
        assert back.course_deg == pytest.approx(course, abs=0.005 + 1e-9)
        assert rmc.mode == {1: "A", 6: "E"}[quality]
    else:
        assert math.isnan(back.lat) and math.isnan(back.lon) and rmc.mode == "N"
    if fix.num_sats >= 4:
        assert back.hdop == pytest.approx(hdop, abs=0.005 + 1e-9)
    assert gsa.prns == [s.prn for s in sats if s.used][:12]
    assert gsvs[0].in_view == len(sats)
    expected = sorted((s.prn, round(s.el_deg), round(s.az_deg) % 360, round(s.snr) if s.snr > 0 else None) for s in sats)
    assert [tuple(slot) for g in gsvs for slot in g.sats] == expected
    assert [(s.svid, s.el_deg, s.az_deg) for s in back.sats] == [x[:3] for x in expected]
    assert [s.used for s in back.sats] == [s.svid in gsa.prns for s in back.sats]
    for line in lines:
        body, cs = line[1:].split("*")
        assert cs == nmea.checksum(body)


def test_multi_gnss_epoch_speaks_nmea_4_10_and_reads_back_every_satellite():
    # As u-blox and SkyTraq receivers write it (tests/data/nmea/gpsd/skytraq-PX1172RH_DS.log): GNGGA, GNRMC, a GNGSA per
    # system with its system id, GPGSV/GLGSV/GAGSV/GBGSV with the signal id; GLONASS numbered 65-96.
    import pynmea2

    rx = GnssReceiver(seed=1)
    world, motion = gw.open_water(), gw.Straight(speed=2.0)
    for t in rx.epochs(2.0):
        fix = rx.fix(world, motion, t)
    lines = fix.nmea()
    talkers = [line[1:6] for line in lines]
    assert talkers[:6] == ["GNGGA", "GNRMC", "GNGSA", "GNGSA", "GNGSA", "GNGSA"]
    assert {t for t in talkers[6:]} == {"GPGSV", "GLGSV", "GAGSV", "GBGSV"}
    ids = {"GPS": 1, "GLONASS": 2, "Galileo": 3, "BeiDou": 4}
    signal_ids = {"GPGSV": "1", "GLGSV": "1", "GAGSV": "7", "GBGSV": "1"}
    for line in lines:
        body, cs = line[1:].split("*")
        assert cs == nmea.checksum(body) and len(line) <= 82
        parsed = pynmea2.parse(line, check=True)
        fields = body.split(",")
        if parsed.sentence_type == "GSA":
            assert int(fields[-1]) in ids.values()
        if parsed.sentence_type == "GSV":
            assert fields[-1] == signal_ids[body[:5]]
            numbers = [int(n) for n in fields[4:-1:4]]
            if body.startswith("GL"):
                assert all(65 <= n <= 96 for n in numbers)
    gsa_used = {}
    for line in lines[2:6]:
        fields = line.split("*")[0].split(",")
        gsa_used[int(fields[-1])] = {int(n) for n in fields[3:15] if n}
    for sat in fix.sats:
        number = sat.prn + (64 if sat.system == "GLONASS" else 0)
        assert (number in gsa_used[ids[sat.system]]) == sat.used
    back = epoch(lines)
    assert back.quality == fix.quality == 2 and back.num_sats == fix.num_sats  # the default receiver is SBAS-corrected
    assert back.lat == pytest.approx(fix.lat, abs=1e-7) and back.lon == pytest.approx(fix.lon, abs=1e-7)
    got = {(s.system, s.svid): (s.signal, s.used, s.el_deg, s.az_deg) for s in back.sats}
    want = {(s.system, s.prn): (s.signal, s.used, round(s.el_deg), round(s.az_deg) % 360) for s in fix.sats}
    assert got == want and {s.system for s in back.sats} == set(ids)


def test_gps_only_receiver_keeps_the_nmea_2_3_dialect():
    rx = GnssReceiver(seed=1, constellations=["GPS"])
    fix = rx.fix(gw.open_water(), gw.Straight(), 0.0)
    lines = fix.nmea()
    assert [line[1:6] for line in lines[:3]] == ["GPGGA", "GPRMC", "GPGSA"] and all(line[1:6] == "GPGSV" for line in lines[3:])
    assert lines[2].split("*")[0].count(",") == 17  # no system id field
