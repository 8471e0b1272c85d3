"""Vessel motion: follows the route exactly, speed profile, wave motion, frames, bad input."""

import numpy as np
import pytest
from analytic_worlds import wall_world
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from sim.trajectory import Trajectory, yaw_pitch_roll_matrices
from worlds.route import Route
from worlds.world import World


@pytest.fixture(scope="module")
def bend_world():
    base = wall_world()
    route = Route.from_waypoints(np.array([[0, 0], [150, 0], [250, 80], [300, 200]]), 30.0, 30.0)
    return World("bend", base.parts, route, base.origin)


def test_calm_vessel_sits_on_the_route_heading_along_it(bend_world):
    traj = Trajectory(bend_world, sea_state=0)
    ts = np.linspace(0, traj.duration, 400)
    poses = traj.poses(ts)
    xy, heading = bend_world.route.at(traj.station(ts))
    np.testing.assert_allclose(poses[:, :2, 3], xy, atol=1e-9)
    np.testing.assert_allclose(poses[:, 2, 3], 0.0, atol=1e-12)
    forward = poses[:, :3, 0]
    np.testing.assert_allclose(np.arctan2(forward[:, 1], forward[:, 0]), np.angle(np.exp(1j * heading)), atol=1e-9)
    np.testing.assert_allclose(forward[:, 2], 0.0, atol=1e-12)


def test_speed_profile_stays_in_band_and_integrates_to_the_route(bend_world):
    traj = Trajectory(bend_world, speed_mps=2.0)
    ts = np.linspace(0, traj.duration, 2000)
    speed = traj.speed(ts)
    assert speed.min() > 1.55 and speed.max() < 2.45
    stations = traj.station(ts)
    numeric = np.gradient(stations, ts)
    np.testing.assert_allclose(numeric[1:-1], speed[1:-1], rtol=1e-3)
    assert traj.station(traj.duration) == pytest.approx(bend_world.route.length, abs=1e-6)
    pos = traj.poses(ts)[:, :2, 3]
    ground_speed = np.linalg.norm(np.gradient(pos, ts, axis=0), axis=1)
    np.testing.assert_allclose(ground_speed[5:-5], speed[5:-5], rtol=2e-2)


def test_waves_give_a_few_degrees_of_roll_and_pitch_and_decimetres_of_heave(bend_world):
    traj = Trajectory(bend_world, sea_state=2, seed=4)
    poses = traj.poses(np.linspace(0, 120, 6000))
    ypr = Rotation.from_matrix(poses[:, :3, :3]).as_euler("ZYX", degrees=True)
    roll, pitch = np.abs(ypr[:, 2]).max(), np.abs(ypr[:, 1]).max()
    assert 0.3 < max(roll, pitch) < 10.0
    assert 0.01 < np.abs(poses[:, 2, 3]).max() < 0.5


def test_a_river_basins_chop_rolls_a_wamv_by_about_a_degree(bend_world):
    """Boston's mean wind along the Charles River Basin's 3 km: a 0.14 m, 1.2 s chop whose waves, shorter than the hull,
    roll and pitch it by tenths of a degree to a degree or two and barely heave it."""
    traj = Trajectory(bend_world, seed=4, wind_waves={"wind_mps": 5.5, "fetch_m": 3000.0})
    poses = traj.poses(np.linspace(0, 200, 8000))
    ypr = Rotation.from_matrix(poses[:, :3, :3]).as_euler("ZYX", degrees=True)
    assert 0.2 < ypr[:, 2].std() < 1.5 and 0.2 < ypr[:, 1].std() < 1.5
    assert np.abs(poses[:, 2, 3]).max() < 0.05
    calm = Trajectory(bend_world, seed=4).poses(np.linspace(0, 200, 8000))
    np.testing.assert_allclose(calm[:, :2, 3], poses[:, :2, 3], atol=1e-9)  # the waves tilt and heave; the track is the route's


def test_single_and_vectorised_poses_agree_and_lidar_pose_applies_the_mount(bend_world):
    traj = Trajectory(bend_world, sea_state=3, mount_xyz=(0.5, 0.0, 1.8), mount_rpy_deg=(0.0, 5.0, 0.0))
    ts = np.array([0.0, 3.3, 17.25])
    batch = traj.poses(ts)
    for t, pose in zip(ts, batch):
        np.testing.assert_allclose(traj.pose(t), pose, atol=1e-12)
        np.testing.assert_allclose(traj.lidar_pose(t), pose @ traj.mount, atol=1e-12)
    assert traj.mount[2, 3] == 1.8


def test_same_seed_same_motion_other_seed_other_waves(bend_world):
    ts = np.linspace(0, 50, 100)
    a = Trajectory(bend_world, sea_state=2, seed=1).poses(ts)
    b = Trajectory(bend_world, sea_state=2, seed=1).poses(ts)
    c = Trajectory(bend_world, sea_state=2, seed=2).poses(ts)
    assert np.array_equal(a, b)
    assert not np.allclose(a, c)


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-np.pi, np.pi), min_size=3, max_size=3))
def test_yaw_pitch_roll_matrix_equals_scipy(angles):
    yaw, pitch, roll = angles
    expected = Rotation.from_euler("ZYX", [yaw, pitch, roll]).as_matrix()
    np.testing.assert_allclose(yaw_pitch_roll_matrices(np.array([yaw]), np.array([pitch]), np.array([roll]))[0], expected, atol=1e-12)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        ({"start_m": 1e6}, "start_m"),
        ({"speed_mps": -1.0}, "speed_mps"),
        ({"sea_state": 9}, "sea_state"),
        ({"wind": 3}, "wind"),
        ({"sea_state": 2, "wind_waves": {"wind_mps": 5.5, "fetch_m": 3000.0}}, "not both"),
        ({"wind_waves": {"wind_mps": 5.5}}, "fetch_m"),
    ],
)
def test_bad_parameters_name_the_key(bend_world, kwargs, message):
    with pytest.raises(ValueError, match=message):
        Trajectory(bend_world, **kwargs)


def test_nan_or_out_of_run_time_is_a_clear_error(bend_world):
    traj = Trajectory(bend_world)
    with pytest.raises(ValueError, match="NaN"):
        traj.pose(float("nan"))
    with pytest.raises(ValueError, match="outside the run"):
        traj.pose(traj.duration + 100.0)
