"""GNSS receiver: exact solutions, DOP, blackout under a deck, coasting, NLOS beside walls, faults.

The receiver here is the consumer profile (autonomous fixes, GGA quality 1, the filter tuned for its metre-level
errors); tests/test_gnss_profiles.py covers the others."""

from __future__ import annotations

import gnss_worlds as gw
import numpy as np
import pytest

from sim import wls
from sim.gnss import GnssReceiver
from sim.multipath import code_multipath_error


def raw_noise_off(**more) -> GnssReceiver:
    return GnssReceiver(profile="consumer", seed=0, filter_mode="raw", noise=gw.NOISE_OFF, **more)


def sat_dirs(fix, used_only=True) -> np.ndarray:
    return np.array([gw.direction(s.az_deg, s.el_deg) for s in fix.sats if s.used or not used_only])


def test_open_sky_noise_off_solution_is_the_antenna_position():
    world = gw.open_water()
    rx = raw_noise_off()
    motion = gw.Straight(speed=2.0, x0=10.0, y=5.0)
    for t in rx.epochs(20.0)[::7]:
        fix = rx.fix(world, motion, t)
        assert fix.quality == 1 and fix.num_sats >= 6
        np.testing.assert_allclose(fix.truth.enu, [10.0 + 2.0 * t, 5.0, 1.3], atol=1e-9)
        assert np.linalg.norm(fix.truth.error) < 1e-3
        assert all(s.los and not s.nlos and s.bias_m == 0.0 for s in fix.truth.sats)


def test_antenna_offset_is_applied_on_base_link():
    world = gw.open_water()
    rx = raw_noise_off(antenna_offset_m=(1.0, 0.5, 2.0))
    fix = rx.fix(world, gw.Static(x=20.0, y=-3.0, yaw_deg=90.0), 0.0)
    np.testing.assert_allclose(fix.truth.enu, [20.0 - 0.5, -3.0 + 1.0, 2.0], atol=1e-12)
    assert np.linalg.norm(fix.enu - fix.truth.enu) < 1e-3


def test_dop_of_a_known_satellite_set_matches_the_hand_computed_value():
    # Zenith plus three satellites at elevation e, 120 deg apart: H^T H is block diagonal with
    # 1.5 cos^2 e for east and north, so HDOP = sqrt(4/3)/cos e and VDOP = 2/(sqrt(3) (1 - sin e)).
    for el in (0.0, 15.0, 30.0, 45.0):
        dirs = np.array([gw.direction(az, el) for az in (10.0, 130.0, 250.0)] + [gw.direction(0.0, 90.0)])
        q = wls.dop(dirs)
        e = np.deg2rad(el)
        assert np.sqrt(q[0, 0] + q[1, 1]) == pytest.approx(np.sqrt(4 / 3) / np.cos(e), rel=1e-9)
        assert np.sqrt(q[2, 2]) == pytest.approx(2 / (np.sqrt(3) * (1 - np.sin(e))), rel=1e-9)


def test_reported_dops_are_those_of_the_satellites_used():
    rx = GnssReceiver(profile="consumer", seed=4)
    fix = rx.fix(gw.open_water(), gw.Static(), 0.0)
    q = wls.dop(sat_dirs(fix))
    assert fix.hdop == pytest.approx(np.sqrt(q[0, 0] + q[1, 1]), rel=1e-6)
    assert fix.vdop == pytest.approx(np.sqrt(q[2, 2]), rel=1e-6)
    assert fix.pdop == pytest.approx(np.sqrt(np.trace(q[:3, :3])), rel=1e-6)
    assert fix.num_sats == sum(s.used for s in fix.sats)


def test_satellites_behind_the_deck_are_blocked_exactly_as_the_slab_test_says():
    world = gw.bridge()
    lo, hi = np.array(gw.DECK[0]), np.array(gw.DECK[1])
    rx = raw_noise_off()
    checked = blocked = 0
    for k, x in enumerate((70.0, 95.0, 104.0, 130.0, 158.0, 175.0)):
        fix = rx.fix(world, gw.Static(x=x), float(k))
        for report, truth in zip(fix.sats, fix.truth.sats):
            expected = gw.ray_hits_box(fix.truth.enu, gw.direction(report.az_deg, report.el_deg), lo, hi)
            assert truth.los == (not expected), (x, report)
            checked += 1
            blocked += expected
    assert blocked > 10 and checked - blocked > 10


def test_under_the_deck_no_raw_fix_then_coast_then_invalid_then_recover():
    world = gw.bridge()
    motion = gw.Straight(speed=1.0, x0=60.0)  # under the deck for x in 100..160, i.e. t in 40..100 s
    raw = raw_noise_off()
    kalman = GnssReceiver(profile="consumer", seed=0, coast_limit_s=8.0)
    qualities = {}
    for t in raw.epochs(130.0)[::5]:  # 1 Hz
        r, k = raw.fix(world, motion, t), kalman.fix(world, motion, t)
        qualities[round(t)] = (r.quality, k.quality)
        if 110.0 <= motion.pose(t)[0, 3] <= 150.0:
            assert r.quality == 0 and r.num_sats < 4 and np.isnan(r.enu).all()
    mid = [qualities[t] for t in range(35, 105)]
    assert any(q == (0, 6) for q in mid), "coasts (dead reckoning) on its filter after losing the fix"
    assert any(q == (0, 0) for q in mid), "reports no fix once the coast limit has passed"
    coast = [t for t in range(30, 110) if qualities[t][1] == 6]
    assert max(coast) - min(coast) <= 8.0 + 1e-9
    assert qualities[125] == (1, 1)


def test_forced_outage_coasts_then_reports_invalid():
    rx = GnssReceiver(profile="consumer", seed=1, coast_limit_s=3.0, forced_outages=[{"start_s": 5.0, "end_s": 12.0}])
    world, motion = gw.open_water(), gw.Straight()
    q = {round(t, 1): rx.fix(world, motion, t).quality for t in rx.epochs(15.0)}
    assert q[4.8] == 1 and q[5.0] == 6 and q[7.8] == 6 and q[8.2] == 0 and q[11.8] == 0 and q[12.0] == 1


def test_after_an_outage_the_filter_follows_a_wrong_estimate_and_converges_slowly():
    # The vessel turns 90 deg during a 10 s outage: the coasted estimate runs straight on.
    class Turn:
        def pose(self, t):
            pose = np.eye(4)
            a = min(max(t - 20.0, 0.0) * 2.0 / 40.0, np.pi / 2)  # 2 m/s; quarter circle of radius 40 m
            pose[:3, 3] = (2.0 * min(t, 20.0) + 40.0 * np.sin(a), 40.0 * (1.0 - np.cos(a)), 0.0)
            pose[1, 3] += 2.0 * max(t - 20.0 - 20.0 * np.pi / 2, 0.0)
            return pose

    rx = GnssReceiver(profile="consumer", seed=0, noise=gw.NOISE_OFF, forced_outages=[{"start_s": 22.0, "end_s": 32.0}])
    world, motion = gw.open_water(), Turn()
    fixes = {round(t, 1): rx.fix(world, motion, t) for t in rx.epochs(90.0)}
    err = {t: np.linalg.norm(f.truth.error[:2]) for t, f in fixes.items()}
    assert err[21.8] < 0.5
    assert err[31.8] > 5.0 and fixes[31.8].quality == 6
    assert fixes[32.0].quality == 1
    assert err[32.0] > 0.5 * err[31.8], "a consumer filter does not jump to the first fix after an outage"
    assert err[32.0] > err[33.0] > err[35.0]
    assert err[89.8] < 0.2


def test_open_sky_error_equals_the_error_where_nothing_blocks_or_reflects():
    rx = GnssReceiver(profile="consumer", seed=4)
    world, motion = gw.open_water(), gw.Straight()
    for t in rx.epochs(30.0):
        fix = rx.fix(world, motion, t)
        np.testing.assert_array_equal(fix.truth.open_sky_error, fix.truth.error)


def test_open_sky_error_separates_the_environment_from_the_nominal_error():
    # Same seed, same range errors: the canyon's receiver and an open-water receiver share the
    # nominal error exactly; the canyon adds NLOS errors on top, and forced faults are not nominal.
    canyon = gw.canyon(north_y=20.0, south_y=-20.0, height=25.0, x0=0.0, x1=300.0)
    forced = [{"start_s": 40.0, "end_s": 50.0}]
    # GPS only: the canyon's sky as a GPS receiver sees it (with four systems, more direct signals dilute the NLOS
    # errors: benchmarks/constellations.py measures how much)
    walled = GnssReceiver(profile="consumer", seed=3, constellations=["GPS"], forced_outages=forced)
    clear = GnssReceiver(profile="consumer", seed=3, constellations=["GPS"])
    motion, open_water = gw.Straight(speed=2.0, x0=0.0), gw.open_water()
    added = []
    for t in walled.epochs(120.0):
        w, c = walled.fix(canyon, motion, t), clear.fix(open_water, motion, t)
        np.testing.assert_allclose(w.truth.open_sky_error, c.truth.error, atol=1e-9)
        if w.quality == 1:
            added.append(np.linalg.norm((w.truth.error - w.truth.open_sky_error)[:2]))
        if 40.0 <= t < 50.0:
            assert w.quality != 1 and np.isfinite(w.truth.open_sky_error).all()
    assert max(added) > 10.0, "NLOS in the canyon adds metres to the nominal error"


def test_wall_canyon_gives_nlos_errors_over_10m_with_low_hdop_that_vanish_in_open_water():
    world = gw.canyon(north_y=20.0, south_y=-20.0, height=25.0, x0=0.0, x1=300.0)
    rx = GnssReceiver(profile="consumer", seed=3)
    motion = gw.Straight(speed=2.0, x0=0.0)
    fixes = [rx.fix(world, motion, t) for t in rx.epochs(300.0)]
    x = np.array([f.truth.enu[0] for f in fixes])
    herr = np.array([np.linalg.norm(f.truth.error[:2]) for f in fixes])
    hdop = np.array([f.hdop for f in fixes])
    nlos = np.array([any(s.nlos for s in f.truth.sats) for f in fixes])
    canyon = x < 300.0
    bad = canyon & nlos & (herr > 10.0) & (hdop < 2.0)
    assert bad.sum() >= 20, "HDOP is not a fault indicator: large NLOS errors with low HDOP"
    open_water = x > 420.0
    assert open_water.sum() > 50 and not nlos[open_water].any()
    assert herr[open_water].max() < 8.0


def test_nlos_bias_is_the_image_method_extra_path_and_drives_the_error():
    north_y, south_y = 20.0, -20.0
    world = gw.canyon(north_y=north_y, south_y=south_y, height=25.0)
    rx = raw_noise_off()
    seen = 0
    for k, (x, y) in enumerate(((50.0, 0.0), (150.0, 8.0), (250.0, -6.0))):
        fix = rx.fix(world, gw.Static(x=x, y=y), float(k))
        distance = {"south": y - south_y, "north": north_y - y}
        for report, truth in zip(fix.sats, fix.truth.sats):
            if not truth.nlos:
                continue
            s = gw.direction(report.az_deg, report.el_deg)
            candidates = [2 * distance["south"] * s[1], -2 * distance["north"] * s[1]]
            assert min(abs(truth.bias_m - c) for c in candidates if c > 0) < 1e-6
            seen += 1
        # With noise off, the error is exactly the WLS image of the truth biases.
        used = [i for i, s in enumerate(fix.sats) if s.used]
        dirs = sat_dirs(fix)
        h = np.hstack([-dirs, np.ones((len(dirs), 1))])
        sigma = rx.config.noise.sigma(np.deg2rad([fix.sats[i].el_deg for i in used]))
        w = 1.0 / sigma**2
        bias = np.array([fix.truth.sats[i].bias_m for i in used])
        predicted = np.linalg.solve((h.T * w) @ h, (h.T * w) @ bias)[:3]
        np.testing.assert_allclose(fix.truth.error, predicted, atol=1e-3)
    assert seen >= 3


def test_forced_bias_shifts_the_raw_solution_by_exactly_the_offset():
    offset = (5.0, -3.0, 2.0)
    rx = raw_noise_off(forced_biases=[{"start_s": 1.0, "end_s": 2.0, "enu_m": offset}])
    world, still = gw.open_water(), gw.Static()
    assert np.linalg.norm(rx.fix(world, still, 0.0).truth.error) < 1e-3
    np.testing.assert_allclose(rx.fix(world, still, 1.0).truth.error, offset, atol=1e-3)
    assert np.linalg.norm(rx.fix(world, still, 2.0).truth.error) < 1e-3


def test_forced_single_satellite_bias_is_reported_in_the_truth():
    rx = raw_noise_off(forced_biases=[{"start_s": 0.0, "end_s": 9.0, "prn": 8, "range_m": 30.0}])  # GPS PRN 8: in view at the default epoch
    fix = rx.fix(gw.open_water(), gw.Static(), 0.0)
    biased = {(s.system, s.prn): s.bias_m for s in fix.truth.sats}
    assert biased.get(("GPS", 8)) == 30.0 and all(b == 0.0 for p, b in biased.items() if p != ("GPS", 8))
    assert np.linalg.norm(fix.truth.error) > 1.0


def test_code_multipath_envelope():
    chip = 299_792_458.0 / 1.023e6
    a, d = 0.4, 0.2
    small = np.array([1.0, 5.0, 10.0])
    np.testing.assert_allclose(code_multipath_error(small, a, d, 0.0), a * small / (1 + a))
    np.testing.assert_allclose(code_multipath_error(small, a, d, np.pi), -a * small / (1 - a))
    plateau = np.array([0.5, 0.7]) * chip
    np.testing.assert_allclose(code_multipath_error(plateau, a, d, 0.0), a * d / 2 * chip)
    assert code_multipath_error(np.array([1.2 * chip]), a, d, 0.0)[0] == 0.0
    delays = np.linspace(0.0, 1.2 * chip, 2001)
    for phase in np.linspace(0.0, 2 * np.pi, 13):
        err = code_multipath_error(delays, a, d, phase)
        assert np.abs(err).max() <= a * d / 2 * chip + 1e-9
        assert np.abs(np.diff(err)).max() < 1.0  # continuous across the pieces


def test_same_seed_same_fixes_different_seed_different_noise():
    world, motion = gw.canyon(), gw.Straight(x0=100.0)

    def run(seed):
        rx = GnssReceiver(profile="consumer", seed=seed)
        return [rx.fix(world, motion, t) for t in rx.epochs(6.0)]

    a, b, c = run(7), run(7), run(8)
    for fa, fb in zip(a, b):
        assert np.array_equal(fa.enu, fb.enu) and fa.sats == fb.sats and fa.nmea() == fb.nmea()
    assert not np.allclose([f.enu for f in a], [f.enu for f in c])


def test_bad_inputs_raise_one_clear_error():
    world, still = gw.open_water(), gw.Static()
    rx = GnssReceiver()
    rx.fix(world, still, 1.0)
    with pytest.raises(ValueError, match="must increase"):
        rx.fix(world, still, 1.0)
    with pytest.raises(ValueError, match="outside the ephemeris file"):
        GnssReceiver(epoch_utc="2031-01-01T00:00:00Z")
    with pytest.raises(ValueError, match="outside the ephemeris file"):
        GnssReceiver().fix(world, still, 400.0 * 86400.0)
    with pytest.raises(ValueError, match="not finite"):
        GnssReceiver().fix(world, gw.Static(x=np.nan), 0.0)
    with pytest.raises(ValueError, match="inside a solid part"):
        GnssReceiver().fix(gw.solid_building(), gw.Static(x=60.0, y=30.0), 0.0)
    with pytest.raises(ValueError, match="rate_hz"):
        GnssReceiver(rate_hz=20.0)
    with pytest.raises(ValueError, match="elevaton_mask"):
        GnssReceiver(elevaton_mask=10.0)
    with pytest.raises(ValueError, match="end_s"):
        GnssReceiver(forced_outages=[{"start_s": 5.0, "end_s": 1.0}])
    with pytest.raises(ValueError, match="filter_mode"):
        GnssReceiver(filter_mode="particle")


def test_antenna_next_to_a_building_is_not_inside_it():
    fix = GnssReceiver(profile="consumer").fix(gw.solid_building(), gw.Static(x=60.0, y=15.0), 0.0)
    assert fix.quality == 1


def test_canal_lock_walls_give_large_nlos_errors_at_low_hdop_open_river_does_not():
    import worlds
    from sim import Trajectory

    def run(name, **trajectory):
        world = worlds.load(name)
        motion = Trajectory(world, **trajectory)
        rx = GnssReceiver(profile="consumer", seed=0, rate_hz=1.0, constellations=["GPS"])  # GPS's sky
        fixes = [rx.fix(world, motion, t) for t in rx.epochs(motion.duration)]
        herr = np.array([np.linalg.norm(f.truth.error[:2]) for f in fixes])
        hdop = np.array([f.hdop for f in fixes])
        nlos = np.array([any(tr.nlos for tr, s in zip(f.truth.sats, f.sats) if s.used) for f in fixes])
        return herr, hdop, nlos

    herr, hdop, nlos = run("canal_lock")
    assert (nlos & (herr > 10.0) & (hdop < 2.0)).sum() >= 20
    herr, hdop, nlos = run("open_river", end_m=1000.0)
    assert not nlos.any() and herr.max() < 8.0 and (hdop < 2.0).all()
