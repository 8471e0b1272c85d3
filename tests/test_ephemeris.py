"""Broadcast ephemerides (sim.ephemeris, sim.constellation) against precise orbits, the ICD equations and orbital facts."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta
from pathlib import Path

import gnss_worlds as gw
import numpy as np
import pytest

from sim import GnssReceiver
from sim import ephemeris as eph
from sim.constellation import CN0_OFFSET_DB, DEFAULT_EPHEMERIS, NMEA_SYSTEM, Constellation, load_ephemeris

DATA = Path(__file__).parent / "data" / "orbits"
NAV_2023 = DATA / "BRDC00WRD_S_20230730000_01D_MN.rnx"
SP3_2023 = DATA / "COD0OPSRAP_20230730000_01D_05M_ORB.SP3"
NOISE_OFF = {"noise": gw.NOISE_OFF}


def precise_orbits() -> dict[tuple[str, int, datetime], np.ndarray]:
    """CODE's rapid orbits (SP3-c, GPS time, km) as {(system letter, PRN, epoch): ECEF metres}."""
    out, epoch = {}, None
    for line in SP3_2023.read_text().splitlines():
        if line.startswith("*"):
            epoch = datetime(*map(int, line[3:].split()[:5]), tzinfo=UTC)  # type: ignore[misc]
        elif line.startswith("P") and epoch is not None:
            out[(line[1], int(line[2:4]), epoch)] = np.array(line[4:46].split(), dtype=float) * 1e3
    return out


@pytest.mark.parametrize(("letter", "tolerance_m"), [("G", 2.5), ("E", 2.5), ("R", 5.0)])
def test_broadcast_positions_match_precise_orbits(letter, tolerance_m):
    # Broadcast orbits agree with precise ones to about a metre (GPS, Galileo) and a few metres (GLONASS): Montenbruck,
    # Steigenberger and Hauschild 2018, GPS Solutions 22:52 (signal-in-space range errors; the 3-D error is larger, and the
    # broadcast GPS/Galileo orbits refer to the antenna, the SP3 to the centre of mass, ~1 m apart).
    nav, checked = eph.read(NAV_2023), 0
    for (system, prn, epoch), reference in precise_orbits().items():
        if system == letter and letter in nav.systems and prn in nav.systems[letter].prn:
            position = nav.positions(letter, np.array([prn]), (epoch - eph.GPS_EPOCH).total_seconds())[0]
            assert np.linalg.norm(position - reference) < tolerance_m, (system, prn, epoch)
            checked += 1
    assert checked == 6  # two satellites at three epochs


def test_is_gps_200_case_by_hand():
    # A circular polar orbit with every correction zero: u = n tk, Omega = -we tk (toe = 0), i = 90 deg, so
    # x = a cos(u) cos(Omega), y = a cos(u) sin(Omega), z = a sin(u) (IS-GPS-200N Table 20-IV).
    a, tk = 26_560e3, 1000.0
    values = np.zeros((1, 28))
    values[0, 7] = np.sqrt(a)  # sqrtA (the fields after the clock: IODE, Crs, dn, M0, Cuc, e, Cus, sqrtA, toe, Cic, ...)
    values[0, 12] = np.pi / 2  # i0
    n = np.sqrt(eph.MU["G"] / a**3)
    u, node = n * tk, -eph.EARTH_RATE["G"] * tk
    expected = a * np.array([np.cos(u) * np.cos(node), np.cos(u) * np.sin(node), np.sin(u)])
    np.testing.assert_allclose(eph.kepler_positions("G", np.array([1]), values, np.array([tk]))[0], expected, atol=1e-6)
    # an eccentric orbit at perigee (M = 0, omega = 0) sits at a (1 - e) on the node line
    values[0, 5] = 0.02
    np.testing.assert_allclose(eph.kepler_positions("G", np.array([1]), values, np.array([0.0]))[0], [a * 0.98, 0.0, 0.0], atol=1e-6)


def test_consecutive_records_agree_where_they_overlap():
    # Two records of one satellite are fitted to different data; where both are valid they give the same position to
    # within the broadcast orbits' accuracy (metres). A wrong element, time system or integration would not.
    nav = load_ephemeris(DEFAULT_EPHEMERIS)
    limits = {"G": 6.0, "E": 3.0, "C": 15.0, "R": 15.0}
    pairs = 0
    for letter, sats in nav.systems.items():
        for prn in np.unique(sats.prn):
            rows = np.nonzero((sats.prn == prn) & sats.healthy)[0]
            rows = rows[np.argsort(sats.ref_s[rows])]
            for first, second in zip(rows[:-1], rows[1:], strict=True):
                gap = sats.ref_s[second] - sats.ref_s[first]
                if not 0.0 < gap <= sats.max_age_s[first]:
                    continue
                middle = sats.ref_s[first] + gap / 2
                values = sats.values[[first, second]]
                dt = middle - sats.ref_s[[first, second]]
                if letter == "R":
                    a, b = eph.glonass_positions(values, dt)
                else:
                    a, b = eph.kepler_positions(letter, np.array([prn, prn]), values, dt)
                assert np.linalg.norm(a - b) < limits[letter], (letter, prn)
                pairs += 1
    assert pairs > 100


def test_orbit_radii_and_periods_are_each_systems():
    constellation = Constellation.load(DEFAULT_EPHEMERIS, ("GPS", "GLONASS", "GALILEO", "BEIDOU"))
    utc = datetime(2018, 7, 29, 14, 0, tzinfo=UTC)
    radius = np.linalg.norm(constellation.ecef(utc), axis=1)
    system = np.array(constellation.system)
    # nominal semi-major axes: GPS 26,560 km, GLONASS 25,510 km, Galileo 29,600 km, BeiDou MEO 27,906 km, IGSO 42,164 km
    bands = {"GPS": (26_000e3, 27_200e3), "GLONASS": (25_400e3, 25_620e3), "GALILEO": (29_500e3, 29_700e3)}
    for name, (lo, hi) in bands.items():
        seen = radius[(system == name) & np.isfinite(radius)]
        assert len(seen) >= 4 and ((seen > lo) & (seen < hi)).all(), name
    beidou = radius[(system == "BEIDOU") & np.isfinite(radius)]
    assert all(27_700e3 < r < 28_100e3 or 41_900e3 < r < 42_500e3 for r in beidou)
    # periods from the elements: GPS half a sidereal day, Galileo 14 h 05 min (Galileo OS SDD), BeiDou MEO 12 h 53 min
    nav = constellation.source
    for letter, hours in (("G", 11.967), ("E", 14.08), ("C", 12.88)):
        sqrt_a = nav.systems[letter].values[:, 7]
        period_h = 2 * np.pi * sqrt_a**3 / np.sqrt(eph.MU[letter]) / 3600.0
        assert (np.abs(period_h - hours) < 0.03).sum() >= 1, letter
    gps_period = 2 * np.pi * nav.systems["G"].values[:, 7] ** 3 / np.sqrt(eph.MU["G"]) / 3600.0
    assert (np.abs(gps_period - 11.967) < 0.02).all()


def test_glonass_positions_from_nodes_are_the_direct_integration():
    nav = load_ephemeris(DEFAULT_EPHEMERIS)
    sats = nav.systems["R"]
    rng = np.random.default_rng(0)
    records = rng.integers(0, len(sats.prn), 200)
    dt = rng.uniform(-1800.0, 1800.0, 200)
    fast = eph.glonass_positions_from(sats.nodes, sats.values[records, 6:9], records, dt)
    np.testing.assert_allclose(fast, eph.glonass_positions(sats.values[records], dt), atol=1e-3)


def test_glonass_period_by_integration():
    # Integrating a GLONASS state through one nodal period (11 h 15 min 44 s, GLONASS ICD 5.1 3.1.1) brings the
    # satellite back to its inertial position near where it began: a check of the force model and the rotating frame.
    nav = eph.read(NAV_2023)
    values = nav.systems["R"].values[:1]
    period = 11 * 3600 + 15 * 60 + 44.0
    start = eph.glonass_positions(values, np.array([0.0]))[0]
    end = eph.glonass_positions(values, np.array([period]))[0]
    turn = eph.EARTH_RATE["R"] * period  # the Earth (and the frame) turned this far meanwhile
    c, s = np.cos(turn), np.sin(turn)
    inertial_end = np.array([c * end[0] - s * end[1], s * end[0] + c * end[1], end[2]])
    assert np.linalg.norm(inertial_end - start) < 30e3  # J2 precesses the node ~0.03 deg a revolution: ~15 km


def test_beidou_geo_stays_over_its_published_longitude():
    # C05 is the BeiDou-2 GEO at 58.75 deg E (China Satellite Navigation Office, BDS constellation status); the GEO branch
    # of BDS-SIS-ICD-B1I-3.0 5.2.4.12 keeps it there; treating it as a MEO/IGSO would not.
    nav = eph.read(NAV_2023)
    sats = nav.systems["C"]
    row = np.nonzero(sats.prn == 5)[0][:1]
    positions = np.array([eph.kepler_positions("C", np.array([5]), sats.values[row], np.array([dt]))[0] for dt in (-3600.0, 0.0, 3600.0)])
    radius = np.linalg.norm(positions, axis=1)
    a, e = sats.values[row, 7][0] ** 2, sats.values[row, 5][0]
    assert abs(a - 42_164e3) < 10e3 and np.all((radius > a * (1 - e) - 1.0) & (radius < a * (1 + e) + 1.0))  # geostationary
    lon = np.rad2deg(np.arctan2(positions[:, 1], positions[:, 0]))
    lat = np.rad2deg(np.arcsin(positions[:, 2] / radius))
    assert np.all(np.abs(lon - 58.75) < 0.5) and np.all(np.abs(lat) < 2.0)
    as_meo = eph.kepler_positions("C", np.array([6]), sats.values[row], np.array([0.0]))[0]
    assert np.linalg.norm(as_meo - positions[1]) > 1000e3


def _in_gps_record(lines: list[str], k: int) -> bool:
    """Whether line k belongs to a GPS record (its record's first line starts with G)."""
    while lines[k].startswith(" "):
        k -= 1
    return lines[k].startswith("G")


def test_a_time_outside_the_file_is_one_clear_error(tmp_path):
    with pytest.raises(
        ValueError, match=r"gnss.epoch_utc 2030-01-01T00:00Z is outside the ephemeris file ELKO00USA_R_20182100000_01D_MN.rnx \(covers 2018-"
    ):
        GnssReceiver(epoch_utc="2030-01-01T00:00:00Z")
    rx = GnssReceiver()
    with pytest.raises(ValueError, match="outside the ephemeris file"):
        rx.fix(gw.open_water(), gw.Static(), 86400.0)
    with pytest.raises(ValueError, match="the run's end 2018-07-29T19:45Z is outside the ephemeris file"):
        GnssReceiver(epoch_utc="2018-07-29T19:00:00Z").check_covers(0.0, 2700.0)
    with pytest.raises(ValueError, match="not found"):
        GnssReceiver(ephemeris="no_such_file.rnx")
    with pytest.raises(ValueError, match="twice"):
        GnssReceiver(constellations=["GPS", "GPS"])
    with pytest.raises(ValueError, match="constellations"):
        GnssReceiver(constellations=["GALILEO2"])
    gps_only = tmp_path / "gps_only.rnx"
    lines = NAV_2023.read_text().splitlines()
    header = lines.index(next(line for line in lines if "END OF HEADER" in line))
    gps_only.write_text("\n".join(lines[: header + 1] + [line for k, line in enumerate(lines) if k > header and _in_gps_record(lines, k)]) + "\n")
    GnssReceiver(ephemeris=str(gps_only), epoch_utc="2023-03-14T01:00:00Z", constellations=["GPS"])
    with pytest.raises(ValueError, match="no healthy records of GLONASS"):
        GnssReceiver(ephemeris=str(gps_only), epoch_utc="2023-03-14T01:00:00Z", constellations=["GPS", "GLONASS"])
    with pytest.raises(ValueError, match="not a RINEX 3 navigation file"):
        eph.read(SP3_2023)


def test_receiver_tracks_the_chosen_systems_at_their_cn0():
    world, still = gw.open_water(), gw.Static()
    gps = GnssReceiver(constellations=["GPS"], **NOISE_OFF).fix(world, still, 0.0)
    assert {s.system for s in gps.sats} == {"GPS"} and gps.quality == 2  # the default receiver is SBAS-corrected
    rx = GnssReceiver(**NOISE_OFF)
    fix = rx.fix(world, still, 0.0)
    assert {s.system for s in fix.sats} == {NMEA_SYSTEM[name] for name in ("GPS", "GLONASS", "GALILEO", "BEIDOU")}
    assert fix.num_sats > gps.num_sats and fix.hdop < gps.hdop
    assert {(s.prn, s.el_deg) for s in gps.sats} == {(s.prn, s.el_deg) for s in fix.sats if s.system == "GPS"}
    noise = rx.config.noise
    by_name = {v: k for k, v in NMEA_SYSTEM.items()}
    for sat in fix.sats:
        expected = noise.cn0(np.deg2rad(sat.el_deg)) + CN0_OFFSET_DB[by_name[sat.system]]
        if expected >= noise.tracking_threshold_dbhz:
            assert sat.snr == pytest.approx(expected, abs=1e-9)
    assert np.linalg.norm(fix.truth.error) < 1e-3  # noise off: the four systems' ranges share one clock exactly


def test_default_epoch_is_inside_the_shipped_file_with_room_for_the_longest_route():
    constellation = Constellation.load()
    start = GnssReceiver().config.epoch_utc
    constellation.check(start)
    constellation.check(start + timedelta(hours=1))


def test_the_record_chosen_per_interval_is_the_one_chosen_afresh_at_every_time():
    """Ephemeris keeps each satellite's record choice between switch times (validity edges, midpoints of reference times):
    at random times, at every switch time and just after each, the kept choice is the direct one."""
    sky = Constellation.load(DEFAULT_EPHEMERIS, ("GPS", "GLONASS", "GALILEO", "BEIDOU"))
    source = sky.source
    lo, hi = (eph.gps_seconds(t, source.leap_seconds) for t in (sky.start_utc, sky.end_utc))
    for letter, rows in sky._groups:
        sats, prn = source.systems[letter], sky.prn[rows]
        switches = eph._switch_times(sats)
        switches = switches[(switches > lo) & (switches < hi)]
        times = np.concatenate([np.random.default_rng(7).uniform(lo, hi, 500), switches, switches + 1e-7, switches + 2e-6, switches - 2e-6])
        for t in np.sort(times):
            assert np.array_equal(source._current(letter, sats, prn, float(t)), eph._nearest_usable(sats, prn, float(t)))
