"""The magnetic compass: heading error statistics without steel match the magnetometer noise, a known dipole at a
known distance gives the analytic deviation, the deviation falls off as the cube of distance, the worlds' steel
disturbs the heading under bridges and at lock gates, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

import sim
import worlds
from sim.magnetic_compass import CompassConfig, MagneticCompass
from sim.magnetism import MOMENT_PER_TONNE, SteelField, earth_field_enu
from sim.trajectory import yaw_pitch_roll_matrices

IDEAL = {"noise_ut": 0.0, "hard_iron_ut": 0.0, "soft_iron": 0.0, "tilt_sigma_deg": 0.0, "lever_m": (0.0, 0.0, 0.0)}


class Spinning:
    """A boat at the origin turning slowly through every heading, rolled and pitched by a few degrees."""

    def __init__(self, rate: float = 0.05, tilt: float = 0.0):
        self.rate, self.tilt = rate, tilt

    def poses(self, ts: np.ndarray) -> np.ndarray:
        ts = np.atleast_1d(ts)
        out = np.zeros((len(ts), 4, 4))
        out[:, :3, :3] = yaw_pitch_roll_matrices(self.rate * ts, self.tilt * np.sin(0.3 * ts), self.tilt * np.cos(0.2 * ts))
        out[:, 3, 3] = 1.0
        return out


def wrap(a: np.ndarray) -> np.ndarray:
    return (a + np.pi) % (2 * np.pi) - np.pi


def heading_errors(compass: MagneticCompass, boat, ts: np.ndarray) -> np.ndarray:
    out = compass.read(boat, ts)
    true = np.arctan2(boat.poses(ts)[:, 1, 0], boat.poses(ts)[:, 0, 0])
    return wrap(np.array([s.yaw for s in out]) - true)


def test_an_ideal_compass_reads_the_true_heading_at_every_heading_and_tilt():
    compass = MagneticCompass(None, CompassConfig(**IDEAL, steel=False))
    err = heading_errors(compass, Spinning(tilt=math.radians(10.0)), np.arange(0.0, 200.0, 0.5))
    assert np.abs(err).max() < 1e-9


def test_without_steel_the_heading_error_is_the_magnetometer_noise():
    """Per-axis noise s on a horizontal field H gives a heading error of sd s / H (small-angle), mean zero."""
    cfg = CompassConfig(**{**IDEAL, "noise_ut": 0.2}, steel=False)
    compass = MagneticCompass(None, cfg, seed=4)
    err = heading_errors(compass, Spinning(tilt=math.radians(5.0)), np.arange(0.0, 4000.0, 0.1))
    horizontal = cfg.intensity_ut * math.cos(math.radians(cfg.inclination_deg))
    assert np.std(err) == pytest.approx(0.2 / horizontal, rel=0.03)
    assert abs(np.mean(err)) < 4.0 * (0.2 / horizontal) / math.sqrt(len(err))


def test_tilt_error_shows_through_the_inclination():
    """A roll error e tilts the vertical field into the horizontal: at heading north the error is about e tan(I)."""
    cfg = CompassConfig(**{**IDEAL, "tilt_sigma_deg": 0.5}, steel=False)
    compass = MagneticCompass(None, cfg, seed=1)
    err = heading_errors(compass, Spinning(rate=0.0), np.arange(0.0, 2000.0, 0.1))  # heading east: a pitch error acts
    assert np.std(err) == pytest.approx(math.radians(0.5) * math.tan(math.radians(cfg.inclination_deg)), rel=0.05)


@pytest.mark.parametrize("distance", [4.0, 8.0, 15.0])
def test_a_known_dipole_gives_the_analytic_deviation(distance):
    """A 10 t steel mass magnetised along east, `distance` m east of a boat heading north: its field there is
    2 mu0/4pi m / d^3 along east, which turns the horizontal field by atan2(He + dB, Hn) - atan2(He, Hn)."""
    moment = 10.0 * MOMENT_PER_TONNE
    steel = SteelField(np.array([[distance, 0.0, 0.0]]), np.array([[moment, 0.0, 0.0]]), np.array([10.0]))
    cfg = CompassConfig(**IDEAL)
    compass = MagneticCompass(None, cfg, steel=steel)
    boat = Spinning(rate=0.0)
    north = np.eye(4)
    north[:3, :3] = yaw_pitch_roll_matrices(np.array([math.pi / 2]), np.zeros(1), np.zeros(1))[0]
    boat.poses = lambda ts: np.repeat(north[None], len(np.atleast_1d(ts)), axis=0)  # type: ignore[method-assign]
    err = heading_errors(compass, boat, np.array([1.0]))[0]
    earth = earth_field_enu(cfg.declination_deg, cfg.inclination_deg, cfg.intensity_ut)
    added = 2e-7 * moment / distance**3 * 1e6
    # the unit takes magnetic north where the disturbed field points: turned clockwise (bearing up) by the push east, so
    # it believes the boat points that much further anticlockwise (ENU yaw up by the same angle)
    want = math.atan2(earth[0] + added, earth[1]) - math.atan2(earth[0], earth[1])
    assert err == pytest.approx(want, rel=1e-9, abs=1e-12)
    assert abs(math.degrees(err)) > 0.1


def test_the_deviation_falls_off_as_the_cube_of_distance():
    moment = 5.0 * MOMENT_PER_TONNE
    steel = SteelField(np.array([[0.0, 0.0, 0.0]]), np.array([[moment, 0.0, 0.0]]), np.array([5.0]))
    field = steel.field_ut(np.array([[20.0, 0.0, 0.0], [40.0, 0.0, 0.0]]))
    assert field[0, 0] / field[1, 0] == pytest.approx(8.0)
    # Breiner's rule of thumb: one tonne, 1 nT at 30 m (on the axis, twice that)
    one = SteelField(np.zeros((1, 3)), np.array([[0.0, 0.0, MOMENT_PER_TONNE]]), np.ones(1)).field_ut(np.array([[30.0, 0.0, 0.0]]))
    assert np.linalg.norm(one) * 1000.0 == pytest.approx(1.0)


@pytest.mark.parametrize("world", ["charles_river", "canal_lock"])
def test_the_worlds_steel_deviates_the_compass_near_it_and_not_in_open_water(world):
    w = worlds.load(world)
    traj = sim.Trajectory(w)
    compass = MagneticCompass(w, CompassConfig(**IDEAL))
    assert compass.steel is not None and compass.steel.tonnes > 100.0
    ts = np.arange(0.0, traj.duration, 1.0)
    err = np.degrees(np.abs(heading_errors(compass, traj, ts)))
    sensor = traj.poses(ts)[:, :3, 3]
    near, _ = cKDTree(compass.steel.positions).query(sensor)
    assert err.max() > 5.0  # under a bridge or beside a gate, a compass misleads by degrees
    assert np.all(err[near > 150.0] < 0.5)  # far from steel it reads true


def test_same_seed_same_readings():
    w = worlds.load("canal_lock")
    traj = sim.Trajectory(w)
    a, b = (MagneticCompass(w, seed=3).read(traj, np.arange(1.0, 5.0, 0.1)) for _ in range(2))
    assert [s.yaw for s in a] == [s.yaw for s in b]
    c = MagneticCompass(w, seed=4).read(traj, np.arange(1.0, 5.0, 0.1))
    assert [s.yaw for s in a] != [s.yaw for s in c]
