"""Scenarios with an IMU and a compass: `sensors` per estimator (default unchanged), the [imu] and [compass] sections
validated by the sim's models with errors that name the key, and a short run that scores the compass."""

from __future__ import annotations

import json

import pytest

import scenarios
from scenarios.spec.library import validate

BASE = {"name": "inertial", "world": "canal_lock", "stretch": {"start_s": 451.0, "end_s": 456.0}, "matchers": [{"id": "gicp", "kind": "gicp"}]}
FED = ["gnss", "odometry", "imu", "compass"]


def test_sensors_default_to_gnss_and_odometry_and_nothing_more_is_simulated():
    s = validate({**BASE, "estimators": [{"id": "ekf", "kind": "ekf"}, {"id": "gps", "kind": "gps_only"}]})
    assert [e.sensors_used for e in s.estimators] == [("gnss", "odometry"), ("gnss",)]
    assert s.imu is None and s.compass is None
    assert "imu" not in s.resolved() and "sensors" not in s.resolved()["estimators"][0]


def test_an_estimator_fed_the_imu_and_compass_gets_them_simulated_with_the_presets():
    s = validate({**BASE, "estimators": [{"id": "ekf", "kind": "ekf", "sensors": FED}], "imu": {"preset": "bmi088"}})
    assert s.imu is not None and s.imu.preset == "bmi088" and s.imu.gyro.noise_density_dps == 0.014
    assert s.compass is not None and s.compass.declination_deg == pytest.approx(-14.04)
    assert s.estimators[0].params["inertial"]["field_ut"] == pytest.approx(s.compass.intensity_ut)
    again = validate(s.resolved())
    assert again.hash == s.hash


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"imu": {"rate_hz": 125.0}}, "imu.rate_hz"),
        ({"imu": {"gyro": {"noise_density_dps": -1.0}}}, "imu.gyro.noise_density_dps"),
        ({"compass": {"rate_hz": 7.0}}, "compass.rate_hz"),
        ({"estimators": [{"id": "ekf", "kind": "ekf", "sensors": ["gnss", "lidar"]}]}, "unknown sensor 'lidar'"),
        ({"estimators": [{"id": "g", "kind": "gps_only", "sensors": ["gnss", "compass"]}]}, "sensors"),
    ],
)
def test_bad_sections_name_the_key(change, message):
    data = {**BASE, "estimators": [{"id": "ekf", "kind": "ekf", "sensors": FED}], **change}
    with pytest.raises(ValueError, match=message):
        scenario = validate(data)
        scenario.estimators[0].build(0)  # a kind that takes no inertial sensors refuses them when built


def test_a_run_with_an_imu_and_a_compass_scores_the_compass(tmp_path):
    """5 s beside canal_lock's lock gates: the compass's own error and how each estimator used it are in metrics.json."""
    s = validate({**BASE, "estimators": [{"id": "ekf", "kind": "ekf"}, {"id": "ekf_imu", "kind": "ekf", "sensors": FED}]})
    result = scenarios.run(s, tmp_path / "run", workers=1, report=False)
    metrics = json.loads((result.out_dir / "metrics.json").read_text())
    assert metrics["compass"]["yaw"]["max"] > 3.0  # the gates' steel deviates it
    assert "compass" in metrics["estimators"]["ekf_imu"] and "compass" not in metrics["estimators"]["ekf"]
    assert metrics["estimators"]["ekf_imu"]["compass"]["disturbed_used"] in (None, 0.0)
    assert not metrics["run"]["failures"]
