"""The compass-gyro check (fusion.compass_check) on analytic cases: a heading bent away by a ramp of 1-3 deg is refused
within a stated time of its onset; an undisturbed compass with the datasheet's errors (sim.magnetic_compass: hard and
soft iron, tilt, noise) beside a gyro with the MTi-630's noise and a bias error of its in-run stability is seldom
refused, straight, weaving or turning full circles; and the check inside the ekf keeps a ramped compass out."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fusion
from fusion.compass_check import CompassGyroBudget, CompassGyroCheck
from fusion.params import InertialParams
from riverbench.samples import HeadingSample, ImuSamples
from sim.magnetic_compass import CompassConfig, MagneticCompass

RATE_HZ = 10.0
ARW = math.radians(0.007)  # MTi-630 gyro noise density, rad/s/sqrt(Hz) (sim.imu.DATASHEETS)
BIAS = math.radians(1.0)  # a raw gyro bias, rad/s (the BMI088's zero-rate offset): the check fits it, whatever it is
SEEDS = range(10)
ONSET_S = 150.0
STRAIGHT, WEAVING = "straight", "weaving_5deg"


def _budget() -> CompassGyroBudget:
    """The defaults the ekf and the pf use (fusion.params.InertialParams), gated at 0.999 (3.29 sigma)."""
    p = InertialParams()
    walk = math.radians(p.gyro_bias_walk_dph) / 3600.0 / 60.0
    return CompassGyroBudget(p.compass_iron_share, walk, p.compass_check_fit_s, p.compass_check_average_s, p.compass_check_min_headings, 3.29)


class Course:
    """A level course: yaw = 0.3 rad + rate t + amplitude sin(2 pi t / period); `.poses(ts)` as sim.Trajectory's."""

    def __init__(self, rate_dps: float = 0.0, amplitude_deg: float = 0.0, period_s: float = 120.0):
        self.rate, self.amplitude, self.period = math.radians(rate_dps), math.radians(amplitude_deg), period_s

    def yaw(self, ts: np.ndarray) -> np.ndarray:
        return 0.3 + self.rate * ts + self.amplitude * np.sin(2.0 * math.pi * ts / self.period)

    def poses(self, ts: np.ndarray) -> np.ndarray:
        yaw = self.yaw(np.asarray(ts, dtype=float))
        out = np.tile(np.eye(4), (len(yaw), 1, 1))
        out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1] = np.cos(yaw), -np.sin(yaw), np.sin(yaw), np.cos(yaw)
        return out


COURSES = {STRAIGHT: Course(), WEAVING: Course(amplitude_deg=5.0)}


def _refused(seed: int, course: Course, duration_s: float, ramp: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(stamps, refused) of a check fed the simulated compass (plus a ramp of (deg, over s) from ONSET_S) and a gyro
    integral of the true yaw with a constant bias (BIAS, sign drawn) and the angle random walk."""
    rng = np.random.default_rng(seed)
    ts = np.arange(1, int(duration_s * RATE_HZ) + 1) / RATE_HZ
    headings = MagneticCompass(None, CompassConfig(steel=False), seed=seed).read(course, ts)
    gyro = course.yaw(ts) + BIAS * rng.choice([-1.0, 1.0]) * ts + np.cumsum(ARW / math.sqrt(RATE_HZ) * rng.standard_normal(len(ts)))
    bent = np.zeros(len(ts)) if ramp is None else math.radians(ramp[0]) * np.clip((ts - ONSET_S) / ramp[1], 0.0, 1.0)
    check = CompassGyroCheck(_budget())
    refused = np.array([not check.check(t, h.yaw + b, g, ARW) for t, h, g, b in zip(ts, headings, gyro, bent)])
    return ts, refused


@pytest.mark.parametrize(
    "course, degrees, over_s, within_s",
    # the stated times, for a boat holding its course as it passes a bridge, straight or weaving +-5 deg every 2 min
    # (measured over 20 seeds: straight 7, 24, 4, 9, 3, 7, 12 s at worst; weaving 12, -, 7, 16, 5, 11, 22 s): the gate
    # lies near 0.3-0.4 deg, reached part way up the ramp plus the 1.5 s the 3 s average lags. Weaving, 1 deg over 30 s
    # is not caught: the residual iron error from heading to heading is as large (the fit absorbs the slow bend).
    [
        (STRAIGHT, 1.0, 10.0, 9.0),
        (STRAIGHT, 1.0, 30.0, 30.0),
        (STRAIGHT, 2.0, 10.0, 5.0),
        (STRAIGHT, 2.0, 30.0, 12.0),
        (STRAIGHT, 3.0, 10.0, 4.0),
        (STRAIGHT, 3.0, 30.0, 9.0),
        (STRAIGHT, 3.0, 60.0, 15.0),
        (WEAVING, 1.0, 10.0, 14.0),
        (WEAVING, 2.0, 10.0, 8.0),
        (WEAVING, 2.0, 30.0, 20.0),
        (WEAVING, 3.0, 10.0, 6.0),
        (WEAVING, 3.0, 30.0, 14.0),
        (WEAVING, 3.0, 60.0, 26.0),
    ],
)
def test_a_ramp_of_one_to_three_degrees_is_refused_within_the_stated_time(course, degrees, over_s, within_s):
    for seed in SEEDS:
        ts, refused = _refused(seed, COURSES[course], ONSET_S + 90.0, (degrees, over_s))
        assert refused[ts < ONSET_S].mean() < 0.01, f"seed {seed}: refused before the onset"
        after = refused & (ts >= ONSET_S)
        first = ts[after][0] - ONSET_S if after.any() else math.inf
        assert first <= within_s, f"seed {seed}: {degrees} deg over {over_s} s first refused {first:.1f} s after its onset"


@pytest.mark.parametrize("course", [Course(), Course(amplitude_deg=20.0), Course(rate_dps=0.5)], ids=["straight", "weaving_20deg", "circling"])
def test_an_undisturbed_compass_is_seldom_refused(course):
    shares = [_refused(seed, course, 600.0)[1].mean() for seed in range(10)]
    assert max(shares) < 0.005, f"refused shares {np.round(shares, 4)}"


def test_a_plateau_stays_refused_and_a_return_is_trusted_again():
    """A 3 deg bend held for 40 s stays refused while the gyro can vouch for its heading; once the compass returns to
    the undisturbed heading its headings are trusted again."""
    for seed in SEEDS:
        check = CompassGyroCheck(_budget())
        ts = np.arange(1, 3001) / RATE_HZ
        bend = np.where((ts >= 150.0) & (ts < 190.0), math.radians(3.0), 0.0)
        noise = math.radians(0.5) * np.random.default_rng(seed).standard_normal(len(ts))  # the MTi's white scatter
        refused = np.array([not check.check(t, 0.2 + b + e, 0.2 + BIAS * t, ARW) for t, b, e in zip(ts, bend, noise)])
        assert refused[(ts >= 152.0) & (ts < 190.0)].all(), f"seed {seed}"
        assert refused[ts >= 195.0].mean() < 0.03, f"seed {seed}"  # measured: at most 1.5 % (the bend's first headings are in the fit)


def _ekf(check: bool):
    params = {"inertial": {"compass_gyro_check": check}}
    return fusion.create("ekf", sensors=("gnss", "odometry", "imu", "compass"), **params)


def test_inside_the_ekf_a_ramped_compass_is_kept_out():
    """An ekf at rest fed a still gyro and a compass bent by 3 deg over 30 s: with the check its heading stays within
    1 deg (what it took in before the bend outgrew the budget); without, the compass (each heading within the 3.3 sigma
    innovation gate of its 1 deg) pulls it all the way."""
    finals = {}
    for check in (True, False):
        est = _ekf(check)
        rng = np.random.default_rng(0)
        est.add_imu(_samples([0.0], np.zeros((1, 3)), np.array([[0.0, 0.0, 9.80]])))  # the filter's clock starts at 0
        est._initialise_from_params(0.0, (0.0, 0.0, math.degrees(0.3)))
        for k in range(1, 1801):
            t = k / RATE_HZ
            stamps = t - 0.1 + np.arange(1, 11) / 100.0
            gyro = np.zeros((10, 3))
            gyro[:, 2] = ARW * 10.0 * rng.standard_normal(10)
            accel = np.tile([0.0, 0.0, 9.80], (10, 1))
            est.add_imu(_samples(stamps, gyro, accel))
            bend = math.radians(3.0) * min(max((t - 60.0) / 30.0, 0.0), 1.0)
            yaw = 0.3 + bend + math.radians(0.3) * rng.standard_normal()
            est.add_heading(HeadingSample(t, yaw, np.array([19.9, -5.0, -47.0]), math.radians(1.0), 66.35))
        finals[check] = math.degrees(math.atan2(est.pose[1, 0], est.pose[0, 0]) - 0.3)
    assert abs(finals[True]) < 1.0, finals
    assert finals[False] > 2.5, finals


def _samples(stamps, gyro, accel) -> ImuSamples:
    return ImuSamples(np.asarray(stamps), gyro, accel, ARW, 0.0006)
