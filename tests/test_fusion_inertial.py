"""The ekf and pf fed an IMU and a compass: a gyro-driven ekf estimates the gyro's bias and holds its heading better
than without, the compass gate refuses a steel-like disturbance (deviation with a disturbed field) and a heading
beyond the gate, the default sensors leave the filters as they were, and estimators without inertial support refuse it."""

from __future__ import annotations

import math

import numpy as np
import pytest

import fusion
from riverbench.samples import HeadingSample
from tests.fusion_streams import Fault, StreamSpec, errors, generate
from tests.inertial_streams import inertial_events, merged, run

SPEC = StreamSpec(duration=120.0, faults=[Fault(60.0, 90.0, (0.0, 0.0), blackout=True)])


@pytest.fixture(scope="module")
def stream():
    base, t_grid, poses = generate(SPEC)
    extra = inertial_events(t_grid, poses, SPEC.duration, gyro_bias_dps=0.3, disturbance=(70.0, 80.0, 15.0))
    return base, extra, t_grid, poses


def feed(kind: str, sensors: tuple[str, ...], stream, **params):
    base, extra, t_grid, poses = stream
    est = fusion.create(kind, sensors=sensors, **params)
    wanted = {"imu"} if "imu" in sensors else set()
    wanted |= {"heading"} if "compass" in sensors else set()
    out = run(est, merged(base, [e for e in extra if e[0] in wanted]))
    err = errors(out, t_grid, poses)
    return est, out, err[np.isfinite(err[:, 0])]


def test_the_ekf_learns_the_gyro_bias_and_holds_its_heading_better(stream):
    """After the start-up alignment has settled (50 s: this stream's GPS alone leaves the heading several degrees off)."""
    _, plain_out, plain = feed("ekf", ("gnss", "odometry"), stream)
    est, gyro_out, gyro = feed("ekf", ("gnss", "odometry", "imu"), stream)
    assert math.degrees(est.x[-1]) == pytest.approx(0.3, abs=0.1)  # the bias state found the gyro's 0.3 deg/s
    settled = lambda out, e: np.degrees(np.abs(e[out["stamp"][-len(e) :] >= 50.0, 2]))
    assert np.percentile(settled(gyro_out, gyro), 95) < min(4.0, np.percentile(settled(plain_out, plain), 95))


@pytest.mark.parametrize("kind", ["ekf", "pf"])
def test_the_compass_gate_refuses_the_disturbed_headings_and_uses_the_others(kind, stream):
    _, out, err = feed(kind, ("gnss", "odometry", "imu", "compass"), stream)
    used = dict(out["heading_used"])
    inside = [u for t, u in used.items() if 70.0 <= t < 80.0]
    outside = [u for t, u in used.items() if t >= 20.0 and not 70.0 <= t < 80.0]
    assert not any(inside)  # 15 deg off with a 5 % stronger field: never used
    assert sum(outside) > 0.5 * (SPEC.duration - 30.0)  # about one per second (compass_interval_s) elsewhere
    assert float(np.percentile(np.degrees(np.abs(err[:, 2])), 95)) < 3.0


def test_a_heading_beyond_the_innovation_gate_is_refused_even_in_an_undisturbed_field(stream):
    est, _, _ = feed("ekf", ("gnss", "odometry", "imu", "compass"), stream)
    yaw, _ = est._heading()
    field = np.array([20.58, 0.0, -47.01])
    dip = math.degrees(math.atan2(47.01, 20.58))
    stamp = est.stamp + 2.0
    assert not est.add_heading(HeadingSample(stamp, yaw + math.radians(20.0), field, math.radians(1.0), dip))
    assert est.add_heading(HeadingSample(stamp + 2.0, yaw, field, math.radians(1.0), dip))


def test_default_sensors_are_gnss_and_odometry_and_the_filter_is_unchanged(stream):
    base, _, _, _ = stream
    a = fusion.create("ekf")
    b = fusion.create("ekf", sensors=("gnss", "odometry"))
    assert a.params.sensors == ("gnss", "odometry") and a.n == 11
    for est in (a, b):
        run(est, base)
    np.testing.assert_array_equal(a.pose, b.pose)


def test_estimators_without_inertial_support_refuse_imu():
    with pytest.raises(ValueError, match="sensors"):
        fusion.create("gps_only", sensors=("gnss", "imu"))
    with pytest.raises(ValueError, match="unknown sensor 'sonar'"):
        fusion.create("ekf", sensors=("gnss", "sonar"))
