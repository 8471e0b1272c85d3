"""The receiver's velocity over ground (RMC speed and course) from Doppler range rates (sim.doppler): exact with the
noise off, the data sheets' accuracy with it on, and beside a wall the WLS image of the reflected paths' rates."""

from __future__ import annotations

import math

import gnss_worlds as gw
import numpy as np

from sim.gnss import GnssReceiver

NO_DOPPLER_NOISE = {"range_rate_zenith_mps": 0.0}


class Diagonal:
    """Level motion at constant velocity (vx, vy) from (x0, y0), heading along it."""

    def __init__(self, vx: float, vy: float, x0: float = 0.0, y0: float = 0.0):
        self.v, self.p0 = np.array([vx, vy]), np.array([x0, y0])

    def pose(self, t: float) -> np.ndarray:
        pose = np.eye(4)
        c, s = self.v / np.linalg.norm(self.v)
        pose[:2, :2] = [[c, -s], [s, c]]
        pose[:2, 3] = self.p0 + self.v * t
        return pose


def ground_velocity(fix) -> np.ndarray:
    course = math.radians(fix.course_deg)
    return fix.speed_mps * np.array([math.sin(course), math.cos(course)])


def test_noise_off_the_velocity_is_the_antennas():
    """Exact truth: 1.5 m/s east and 1 m/s north, antenna 1 m ahead of base_link and 1.3 m up."""
    rx = GnssReceiver(profile="consumer", seed=0, noise=gw.NOISE_OFF, doppler=NO_DOPPLER_NOISE, antenna_offset_m=(1.0, 0.0, 1.3))
    motion = Diagonal(1.5, 1.0)
    for t in rx.epochs(10.0)[::5]:
        fix = rx.fix(gw.open_water(), motion, t)
        assert fix.quality == 1
        np.testing.assert_allclose(ground_velocity(fix), [1.5, 1.0], atol=1e-6)


def test_open_sky_velocity_error_is_the_data_sheets():
    """u-blox NEO-M8N and ZED-F9P data sheets: velocity accuracy 0.05 m/s (50 %); independent of the position's metres."""
    world, motion = gw.open_water(), gw.Straight(speed=2.0)
    for profile in ("consumer", "sbas"):
        rx = GnssReceiver(profile=profile, seed=4)
        fixes = [rx.fix(world, motion, t) for t in rx.epochs(200.0)]
        err = np.array([np.linalg.norm(ground_velocity(f) - [2.0, 0.0]) for f in fixes])
        assert 0.03 < np.median(err) < 0.07, (profile, np.median(err))
        assert np.percentile(err, 95) < 0.2


def test_beside_a_wall_the_velocity_error_is_the_wls_image_of_the_reflected_paths_rates():
    """Noise off, moving towards a facade: each reflected satellite's range rate carries its extra path's rate of change
    (the image method), and the velocity error is their weighted least-squares image through the used geometry."""
    world = gw.canyon(north_y=20.0, south_y=-20.0, height=25.0)
    rx = GnssReceiver(profile="consumer", seed=0, noise=gw.NOISE_OFF, doppler=NO_DOPPLER_NOISE, filter_mode="raw")
    motion = Diagonal(2.0, 0.6, x0=50.0, y0=-15.0)
    previous, checked = None, 0
    for t in rx.epochs(40.0):
        fix = rx.fix(world, motion, t)
        if previous is not None and fix.quality:
            before = {(s.system, s.prn): s.bias_m for s in previous.truth.sats if s.nlos}
            used = [(r, s) for r, s in zip(fix.sats, fix.truth.sats) if r.used and ((s.system, s.prn) in before) == s.nlos]
            rates = np.array([(s.bias_m - before[s.system, s.prn]) / 0.2 if s.nlos else 0.0 for _, s in used])
            if rates.any():
                dirs = np.array([gw.direction(r.az_deg, r.el_deg) for r, _ in used])
                g = np.hstack([-dirs, np.ones((len(dirs), 1))])
                w = np.sin(np.deg2rad([r.el_deg for r, _ in used])) ** 2
                predicted = np.linalg.solve((g.T * w) @ g, (g.T * w) @ rates)[:2]
                np.testing.assert_allclose(ground_velocity(fix) - motion.v, predicted, atol=2e-3)
                checked += 1
        previous = fix
    assert checked >= 20


def test_through_an_outage_the_velocity_is_the_filters_coast():
    """Under the deck there is no range rate to measure: the dead-reckoned fixes (GGA quality 6) report the navigation
    filter's constant velocity, as they report its position."""
    rx = GnssReceiver(profile="consumer", seed=1, doppler=NO_DOPPLER_NOISE)
    motion = gw.Straight(speed=2.0, x0=60.0)
    fixes = [rx.fix(gw.bridge(), motion, t) for t in rx.epochs(40.0)]
    coasting = [f for f in fixes if f.quality == 6]
    assert coasting and all(math.isfinite(f.speed_mps) for f in coasting)
    assert len({round(f.speed_mps, 9) for f in coasting}) <= 2  # constant velocity (a new coast may start once)
