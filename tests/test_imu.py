"""The IMU model: exact kinematics (rest, a constant-rate turn, analytic vs finite differences), the datasheet
figures read back from the simulated sensor's Allan deviation by allantools, batches, determinism, bad config."""

from __future__ import annotations

import math

import allantools
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError

from sim.imu import STANDARD_GRAVITY, Imu, ImuConfig, samples_per_period
from sim.kinematics import _finite_difference, body_motion, normal_gravity
from sim.plane_motion import PlaneMotion
from sim.trajectory import yaw_pitch_roll_matrices
from sim.waves import WaveMotion

QUIET = {
    "gyro": {
        "noise_density_dps": 0.0,
        "bias_instability_dph": 0.0,
        "bias_random_walk_dphrh": 0.0,
        "turn_on_bias_dps": 0.0,
        "scale_factor": 0.0,
        "misalignment_deg": 0.0,
        "resolution_dps": 0.0,
    },
    "accel": {
        "noise_density_ug": 0.0,
        "bias_instability_ug": 0.0,
        "bias_random_walk_ugrs": 0.0,
        "turn_on_bias_mg": 0.0,
        "scale_factor": 0.0,
        "misalignment_deg": 0.0,
        "resolution_ug": 0.0,
    },
}
"""Overrides that leave an ideal sensor: its output is the truth."""


class Circle:
    """A vessel turning at a constant rate on a circle (signed radius m: centre to the left when > 0; rate rad/s; rate 0
    is a boat at rest), level,
    optionally heeled by a constant roll: analytic plane motion and exact poses."""

    def __init__(self, radius: float, rate: float, roll: float = 0.0):
        self.radius, self.rate, self.roll = radius, rate, roll
        zero = np.zeros(1)  # a steady heel: one wave component of frequency 0 at phase pi/2
        self.waves = WaveMotion(omega=zero, phase=np.full(1, math.pi / 2), heave_amp=zero, roll_amp=np.full(1, roll), pitch_amp=zero)

    def plane_motion(self, ts: np.ndarray) -> PlaneMotion:
        a = self.rate * ts
        r, w = self.radius, self.rate
        xy = r * np.stack([np.sin(a), -np.cos(a)], axis=-1)
        velocity = r * w * np.stack([np.cos(a), np.sin(a)], axis=-1)
        acceleration = r * w * w * np.stack([-np.sin(a), np.cos(a)], axis=-1)
        return PlaneMotion(xy, a, velocity, acceleration, np.full(len(ts), w))

    def poses(self, ts: np.ndarray) -> np.ndarray:
        ts = np.atleast_1d(ts)
        plane = self.plane_motion(ts)
        out = np.zeros((len(ts), 4, 4))
        out[:, :3, :3] = yaw_pitch_roll_matrices(plane.yaw, np.zeros(len(ts)), np.full(len(ts), self.roll))
        out[:, :2, 3] = plane.xy
        out[:, 3, 3] = 1.0
        return out


def ideal(preset: str = "mti630", **more) -> ImuConfig:
    return ImuConfig(preset=preset, **QUIET, **more)


def test_at_rest_the_accelerometer_reads_plus_g_up_and_the_gyro_the_earth_rate():
    imu = Imu(ideal(), origin_lat_deg=42.3539)
    out = imu.sample(Circle(0.0, 0.0), imu.times(0.0, 1.0))
    g = normal_gravity(42.3539)
    assert 9.80 < g < 9.81
    np.testing.assert_allclose(out.accel, np.tile([0.0, 0.0, g], (len(out), 1)), atol=1e-12)
    lat = math.radians(42.3539)
    np.testing.assert_allclose(out.gyro, np.tile([0.0, 7.292115e-5 * math.cos(lat), 7.292115e-5 * math.sin(lat)], (len(out), 1)), atol=1e-15)


def test_a_heeled_boat_at_rest_sees_gravity_tilted_into_its_frame():
    roll = math.radians(20.0)
    imu = Imu(ideal(earth_rate=False))
    out = imu.sample(Circle(0.0, 0.0, roll=roll), imu.times(0.0, 0.5))
    np.testing.assert_allclose(out.accel[0], imu.gravity * np.array([0.0, math.sin(roll), math.cos(roll)]), atol=1e-12)


@pytest.mark.parametrize("rate_dps", [-10.0, 3.0, 30.0])
def test_a_constant_rate_turn_reads_the_rate_and_the_centripetal_force(rate_dps):
    rate = math.radians(rate_dps)
    radius = math.copysign(20.0, rate)  # the centre on the side it turns to: forward speed radius x rate > 0
    imu = Imu(ideal(earth_rate=False))
    out = imu.sample(Circle(radius, rate), imu.times(0.0, 5.0))
    np.testing.assert_allclose(out.gyro, np.tile([0.0, 0.0, rate], (len(out), 1)), atol=1e-14)
    # the boat's velocity is along its x axis; the force towards the centre is to its left when turning left (rate > 0)
    np.testing.assert_allclose(out.accel, np.tile([0.0, radius * rate**2, imu.gravity], (len(out), 1)), atol=1e-12)


def test_analytic_derivatives_agree_with_finite_differences_of_the_exact_poses():
    boat = Circle(15.0, math.radians(12.0), roll=math.radians(5.0))
    ts = np.linspace(0.0, 20.0, 101)
    lever = np.array([0.5, -0.3, 1.2])
    exact = body_motion(boat, ts, 9.8, np.zeros(3), lever)
    numeric = _finite_difference(boat, ts, 9.8, np.zeros(3), lever)
    np.testing.assert_allclose(numeric.omega, exact.omega, atol=1e-8)
    np.testing.assert_allclose(numeric.specific_force, exact.specific_force, atol=1e-5)


def test_saturation_and_quantisation():
    imu = Imu(ImuConfig(preset="bmi088", **{"gyro": {**QUIET["gyro"], "range_dps": 20.0, "resolution_dps": 0.5}}, earth_rate=False))
    out = imu.sample(Circle(5.0, math.radians(30.0)), imu.times(0.0, 1.0))
    assert np.all(out.gyro[:, 2] == math.radians(20.0))
    lsb = math.radians(0.5)
    np.testing.assert_allclose(out.gyro / lsb, np.round(out.gyro / lsb), atol=1e-9)


def test_same_seed_same_output_and_another_seed_another():
    boat = Circle(30.0, math.radians(5.0))
    runs = [Imu(ImuConfig(preset="bmi088"), seed=s).sample(boat, np.arange(1, 200) * 0.01) for s in (7, 7, 8)]
    np.testing.assert_array_equal(runs[0].gyro, runs[1].gyro)
    np.testing.assert_array_equal(runs[0].accel, runs[1].accel)
    assert not np.array_equal(runs[0].gyro, runs[2].gyro)


@settings(max_examples=20, deadline=None)
@given(st.lists(st.integers(1, 60), min_size=1, max_size=5))
def test_batches_continue_one_record(splits):
    """Sampling in batches gives the record one call gives: the biases and the noise stream carry over."""
    boat = Circle(30.0, math.radians(5.0))
    ts = np.arange(1, 1 + sum(splits)) * 0.01
    whole = Imu(ImuConfig(preset="bmi088"), seed=3).sample(boat, ts)
    imu, parts, i = Imu(ImuConfig(preset="bmi088"), seed=3), [], 0
    for n in splits:
        parts.append(imu.sample(boat, ts[i : i + n]).gyro)
        i += n
    np.testing.assert_allclose(np.concatenate(parts), whole.gyro, rtol=0, atol=1e-15)


def test_bad_configuration_names_the_key():
    with pytest.raises(ValidationError, match="gyro.noise_density_dps"):
        ImuConfig(gyro={"noise_density_dps": -0.01})
    with pytest.raises(ValidationError, match="rate_hz"):
        ImuConfig(rate_hz=800.0)
    with pytest.raises(ValueError, match="imu.rate_hz"):
        samples_per_period(125.0, 0.1)
    assert samples_per_period(100.0, 0.1) == 10
    with pytest.raises(ValidationError, match="gyro.bias_instability"):
        ImuConfig(gyro={"bias_instability_dph": 0.01})  # below what the white noise alone gives
    with pytest.raises(ValueError, match="must increase"):
        imu = Imu()
        imu.sample(Circle(0.0, 0.0), np.array([1.0, 0.5]))


# ---- Allan deviation: the datasheet figures come back -------------------------------------------------------
def allan(record: np.ndarray, rate: float, taus: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan deviation (allantools) averaged as a variance over the record's columns."""
    out = [allantools.oadev(record[:, k], rate=rate, data_type="freq", taus=taus) for k in range(record.shape[1])]
    return out[0][0], np.sqrt(np.mean([o[1] ** 2 for o in out], axis=0))


def static_record(preset: str, rate_hz: float, duration_s: float, units: int, **overrides) -> tuple[np.ndarray, np.ndarray]:
    """(gyro, accel) of `units` simulated parts at rest, each axis a column."""
    gyro, accel = [], []
    for unit in range(units):
        imu = Imu(ImuConfig(preset=preset, rate_hz=rate_hz, **overrides), seed=unit)
        chunks = [imu.sample(Circle(0.0, 0.0), imu.times(t, min(t + 20000.0, duration_s))) for t in np.arange(0.0, duration_s, 20000.0)]
        gyro.append(np.concatenate([c.gyro for c in chunks]))
        accel.append(np.concatenate([c.accel for c in chunks]))
    return np.hstack(gyro), np.hstack(accel)


def read_noise_density(record: np.ndarray, rate: float) -> float:
    """Noise density from the -1/2 slope around tau = 1 s: median of ADEV(tau) sqrt(tau) over 0.3..3 s."""
    taus, adev = allan(record, rate, np.logspace(-1, 1, 21))
    keep = (taus >= 0.3) & (taus <= 3.0)
    return float(np.median(adev[keep] * np.sqrt(taus[keep])))


def read_bias_instability(record: np.ndarray, rate: float, duration: float) -> float:
    """The Allan deviation's minimum / 0.664 (IEEE Std 952)."""
    _, adev = allan(record, rate, np.logspace(0, math.log10(duration / 8), 50))
    return float(adev.min()) / 0.664


@pytest.mark.parametrize("preset", ["mti630", "bmi088"])
def test_noise_densities_read_back_from_the_allan_deviation(preset):
    cfg = ImuConfig(preset=preset)
    gyro, accel = static_record(preset, 100.0, 300.0, 2)
    assert math.degrees(read_noise_density(gyro, 100.0)) == pytest.approx(cfg.gyro.noise_density_dps, rel=0.10)
    assert read_noise_density(accel, 100.0) / (1e-6 * STANDARD_GRAVITY) == pytest.approx(cfg.accel.noise_density_ug, rel=0.10)


# at 1 Hz the BMI088's 16-bit LSB would add its own white noise; the readback checks the noise model, so it is turned off
FLOAT_OUTPUT = {"gyro": {"resolution_dps": 0.0}, "accel": {"resolution_ug": 0.0}}


@pytest.mark.parametrize(
    ("preset", "sensor", "duration_s"),
    [("mti630", "gyro", 4000.0), ("mti630", "accel", 12000.0), ("bmi088", "gyro", 200000.0)],
)
def test_bias_instability_reads_back_from_the_allan_floor(preset, sensor, duration_s):
    """A long static record at 1 Hz (8 units, 3 axes each): the floor of the -1/2 .. +1/2 slopes / 0.664."""
    cfg = ImuConfig(preset=preset)
    gyro, accel = static_record(preset, 1.0, duration_s, 8, **FLOAT_OUTPUT)
    if sensor == "gyro":
        read, want = math.degrees(read_bias_instability(gyro, 1.0, duration_s)) * 3600.0, cfg.gyro.bias_instability_dph
    else:
        read, want = read_bias_instability(accel, 1.0, duration_s) / (1e-6 * STANDARD_GRAVITY), cfg.accel.bias_instability_ug
    assert read == pytest.approx(want, rel=0.12)


@pytest.mark.slow
def test_bias_instability_of_the_consumer_part_at_its_output_rate():
    """The BMI088 at 20 Hz with its 16-bit output, 3 units for 42 h each: noise density and bias stability both read back."""
    cfg = ImuConfig(preset="bmi088", rate_hz=20.0)
    gyro, _ = static_record("bmi088", 20.0, 150000.0, 3)
    assert math.degrees(read_noise_density(gyro, 20.0)) == pytest.approx(cfg.gyro.noise_density_dps, rel=0.10)
    assert math.degrees(read_bias_instability(gyro, 20.0, 150000.0)) * 3600.0 == pytest.approx(cfg.gyro.bias_instability_dph, rel=0.15)
