"""HDL-32E model against analytic geometry and exact ground truth."""

import numpy as np
import open3d as o3d
import pytest
from analytic_worlds import cylinder_world, front_wall_world, ground_world, open_water_world, wall_world

from sim.lidar import FIRING_CYCLE_S, HDL32E, HDL32E_ELEVATION_DEG, LASER_INTERVAL_S
from sim.trajectory import Trajectory
from worlds.materials import GLASS

EXACT = dict(range_noise_m=0.0, range_resolution_m=0.0, dropout_rate=0.0, beam_divergence_mrad=0.0)  # an ideal pencil beam


def to_world(traj, scan):
    """Each point through the true lidar pose at its own firing time."""
    poses = traj.lidar_poses(scan.stamp + scan.points["time"].astype(np.float64))
    return np.einsum("nab,nb->na", poses[:, :3, :3], scan.xyz) + poses[:, :3, 3]


@pytest.fixture(scope="module")
def wall():
    world = wall_world(distance_m=10.0)
    return world, Trajectory(world, sea_state=2, seed=3)


def test_geometry_follows_the_datasheet():
    lidar = HDL32E(rate_hz=10.0)
    assert lidar.elevation_deg[0] == -30.67 and lidar.elevation_deg[15] == 0.0 and lidar.elevation_deg[31] == 10.67
    assert lidar.n_firings == 2170
    assert lidar.azimuth_step_deg == pytest.approx(0.1659, abs=1e-4)
    assert HDL32E(rate_hz=5.0).n_firings == 4340 and HDL32E(rate_hz=20.0).n_firings == 1085


def test_wall_ranges_are_exact_without_noise_and_points_lie_on_the_face(wall):
    world, traj = wall
    scan = HDL32E(**EXACT).scan(world, traj, 5.0)
    on_wall = world.face_part[0] != scan.points["label"]
    assert on_wall.sum() > 5000
    pw = to_world(traj, scan)[on_wall]
    np.testing.assert_allclose(pw[:, 1], 10.0, atol=1e-3)


def test_wall_range_noise_has_the_configured_sigma_and_2mm_quantum(wall):
    world, traj = wall
    exact = HDL32E(**EXACT, seed=1).scan(world, traj, 5.0)
    noisy = HDL32E(range_noise_m=0.02, dropout_rate=0.0, beam_divergence_mrad=0.0, seed=1).scan(world, traj, 5.0)
    assert len(noisy) == len(exact)  # noise is drawn after the same detection draws
    r_exact = np.linalg.norm(exact.xyz, axis=1)
    r_noisy = np.linalg.norm(noisy.xyz, axis=1)
    err = r_noisy - r_exact
    assert abs(err.mean()) < 2e-3
    assert 0.018 < err.std() < 0.022
    quanta = r_noisy / 0.002
    np.testing.assert_allclose(quanta, np.round(quanta), atol=2e-3)


def test_cylinder_points_lie_at_its_radius():
    world = cylinder_world(radius_m=1.0, centre=(40.0, 8.0))
    traj = Trajectory(world, sea_state=1)
    scan = HDL32E(**EXACT).scan(world, traj, 10.0)
    pier = scan.points["label"] == 1
    assert pier.sum() > 200
    pw = to_world(traj, scan)[pier]
    radius = np.hypot(pw[:, 0] - 40.0, pw[:, 1] - 8.0)
    np.testing.assert_allclose(radius, 1.0, atol=1e-3)  # 256-gon sagitta is 0.08 mm


def test_ring_elevation_and_time_fields_match_the_sensor_model(wall):
    world, traj = wall
    lidar = HDL32E(**EXACT)
    scan = lidar.scan(world, traj, 7.0)
    p = scan.points
    elevation = np.degrees(np.arctan2(p["z"], np.hypot(p["x"], p["y"])))
    np.testing.assert_allclose(elevation, HDL32E_ELEVATION_DEG[p["ring"]], atol=1e-3)
    firing = (p["time"].astype(np.float64) - p["ring"] * LASER_INTERVAL_S) / FIRING_CYCLE_S
    np.testing.assert_allclose(firing, np.round(firing), atol=1e-3)
    assert p["time"].min() >= 0 and p["time"].max() < lidar.revolution_s
    # clockwise spin from the rear: azimuth = 180 deg - 360 deg * rate * time
    azimuth = np.degrees(np.arctan2(p["y"], p["x"]))
    expected = 180.0 - 360.0 * 10.0 * p["time"].astype(np.float64)
    wrapped = (azimuth - expected + 180.0) % 360.0 - 180.0
    np.testing.assert_allclose(wrapped, 0.0, atol=1e-3)


def test_every_point_lies_on_the_world_mesh():
    world = cylinder_world()
    traj = Trajectory(world, sea_state=3, seed=5)
    scan = HDL32E(**EXACT, water_return_prob=1.0).scan(world, traj, 3.0)
    pw = to_world(traj, scan)
    sample = np.random.default_rng(0).choice(len(pw), size=min(3000, len(pw)), replace=False)
    distance = world.raycasting_scene.compute_distance(o3d.core.Tensor(pw[sample].astype(np.float32))).numpy()
    assert distance.max() < 1e-3


def test_moving_sensor_distorts_a_wall_by_exactly_the_motion_and_deskew_restores_it():
    world = front_wall_world(x_m=40.0)
    traj = Trajectory(world, speed_mps=2.0, speed_variation=0.0, sea_state=0)
    lidar = HDL32E(**EXACT, start_azimuth_deg=0.0)  # the cut straight ahead: the wall is seen first and last
    scan = lidar.scan(world, traj, 2.0)
    on_wall = (scan.points["label"] == 1) & (np.abs(scan.points["y"]) < 30)
    p = scan.points[on_wall]
    # the raw x of the wall, seen from the frame of each firing, shrinks by the distance travelled
    raw_x = p["x"].astype(np.float64)
    travelled = 2.0 * p["time"].astype(np.float64)
    np.testing.assert_allclose(raw_x + travelled, raw_x[0] + travelled[0], atol=2e-3)
    assert raw_x.max() - raw_x.min() == pytest.approx(2.0 * np.ptp(p["time"]), abs=2e-3)
    assert raw_x.max() - raw_x.min() > 0.15
    # de-skew every point into the lidar frame at the scan stamp with the true poses: a plane again
    ref = np.linalg.inv(traj.lidar_pose(scan.stamp))
    pw = to_world(traj, scan)[on_wall]
    deskewed = pw @ ref[:3, :3].T + ref[:3, 3]
    assert np.ptp(deskewed[:, 0]) < 2e-3


def test_water_returns_almost_nothing_but_ground_returns():
    lidar = HDL32E(seed=2)
    water = open_water_world()
    ground = ground_world()
    n_water = len(lidar.scan(water, Trajectory(water), 1.0))
    n_ground = len(lidar.scan(ground, Trajectory(ground), 1.0))
    assert n_water < 0.002 * lidar.n_firings * 32
    assert n_ground > 0.5 * lidar.n_firings * 23  # 23 of 32 lasers point down


def test_pontoons_occlude_the_lowest_laser_where_they_are():
    world = ground_world()
    traj = Trajectory(world)

    def lowest_over_pontoons(occlusion: bool) -> int:
        # the -30.67 deg laser from 1.8 m reaches the 0.5 m pontoon tops 2.19 m out: the pontoons
        # (y = 0.7..1.2 m each side, ending 2.45 m fore and aft) cover azimuths of about 19-33 deg
        p = HDL32E(**EXACT, self_occlusion=occlusion).scan(world, traj, 1.0).points
        azimuth = np.abs(np.degrees(np.arctan2(p["y"], p["x"])))
        over = ((azimuth > 20) & (azimuth < 30)) | ((azimuth > 150) & (azimuth < 160))
        return int(((p["ring"] == 0) & over).sum())

    assert lowest_over_pontoons(False) > 100
    assert lowest_over_pontoons(True) == 0


def test_intensity_grows_with_reflectivity_and_falls_with_incidence():
    concrete, glass = wall_world(), wall_world(material=GLASS)
    lidar = HDL32E(**EXACT)
    i_concrete = lidar.scan(concrete, Trajectory(concrete), 1.0).points
    i_glass = lidar.scan(glass, Trajectory(glass), 1.0).points
    assert np.median(i_concrete["intensity"][i_concrete["label"] == 1]) > 2 * np.median(i_glass["intensity"][i_glass["label"] == 1])
    wall_pts = i_concrete[i_concrete["label"] == 1]
    ahead = np.abs(wall_pts["x"]) / np.hypot(wall_pts["x"], wall_pts["y"])  # sine of the incidence angle
    assert np.corrcoef(ahead, wall_pts["intensity"])[0, 1] < -0.5


def test_beyond_max_range_nothing_returns():
    world = wall_world(distance_m=10.0)
    near = HDL32E(**EXACT, max_range_m=100.0).scan(world, Trajectory(world), 1.0)
    short = HDL32E(**EXACT, max_range_m=12.0).scan(world, Trajectory(world), 1.0)
    assert np.linalg.norm(near.xyz, axis=1).max() > 50
    assert np.linalg.norm(short.xyz, axis=1).max() <= 12.0
    assert 0 < len(short) < len(near)


def test_dry_hits_bound_the_points_and_water_gives_none(wall):
    world, traj = wall
    lidar = HDL32E(**EXACT)
    bound = lidar.dry_hits(world, traj, 5.0)
    labels = lidar.scan(world, traj, 5.0).points["label"]
    dry = int((~world.part_is_water[labels]).sum())
    assert 0.97 * bound <= dry <= bound  # the same rays; only detection (1 - exp(-k power) < 1) loses some
    water = open_water_world()
    assert lidar.dry_hits(water, Trajectory(water), 1.0) == 0
    assert HDL32E(**EXACT, max_range_m=12.0).dry_hits(world, traj, 5.0) < bound


def test_scheduled_blinding_removes_most_points(wall):
    world, traj = wall
    lidar = HDL32E(blinding=[(4.95, 5.05)])
    normal = len(lidar.scan(world, traj, 4.8))
    blinded = len(lidar.scan(world, traj, 5.0))
    assert blinded < 0.1 * normal


def test_same_seed_identical_scans_other_seed_other_noise(wall):
    world, traj = wall
    a = HDL32E(seed=7).scan(world, traj, 6.0).points
    b = HDL32E(seed=7).scan(world, traj, 6.0).points
    c = HDL32E(seed=8).scan(world, traj, 6.0).points
    assert np.array_equal(a, b)
    assert len(a) != len(c) or not np.array_equal(a["x"], c["x"])


@pytest.mark.parametrize(
    "kwargs, key",
    [({"rate_hz": 30.0}, "rate_hz"), ({"min_range_m": 200.0}, "min_range_m"), ({"beams": 64}, "beams")],
)
def test_bad_sensor_parameters_name_the_key(kwargs, key):
    with pytest.raises(ValueError, match=key):
        HDL32E(**kwargs)


def test_nan_start_time_is_a_clear_error(wall):
    world, traj = wall
    with pytest.raises(ValueError, match="not finite"):
        HDL32E().scan(world, traj, float("nan"))
