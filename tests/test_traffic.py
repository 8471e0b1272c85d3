"""Moving boats: the LiDAR sees each at every ray's firing time, they block GNSS signals, and the traffic kinematics."""

import csv
from dataclasses import dataclass

import numpy as np
import pytest
import trimesh
from analytic_worlds import wall_world
from gnss_worlds import NOISE_OFF, Static, open_water
from pydantic import ValidationError

import scenarios
import worlds
from scenarios.pipeline import files
from sim.boats import BOATS, boat
from sim.gnss import GnssReceiver
from sim.lidar import HDL32E
from sim.movers import AlongRoute, Chase, Mover, level_poses
from sim.scene import Scene
from sim.traffic import Traffic, TrafficConfig, build_traffic
from sim.trajectory import Trajectory
from worlds.materials import STEEL

EXACT = {"range_noise_m": 0.0, "range_resolution_m": 0.0, "dropout_rate": 0.0}
HALF = np.array([2.0, 1.0, 1.5])  # half extents of the test box boat, centred 1 m above the waterline


def box_boat(motion, material=STEEL) -> Mover:
    mesh = trimesh.creation.box(extents=2 * HALF)
    mesh.apply_translation((0.0, 0.0, 1.0))
    return Mover("box", mesh, material, motion)


def world_points(traj, scan):
    """Each point through the true lidar pose at its own firing time."""
    poses = traj.lidar_poses(scan.stamp + scan.points["time"].astype(np.float64))
    return np.einsum("nab,nb->na", poses[:, :3, :3], scan.xyz) + poses[:, :3, 3]


def in_body(mover, times, points):
    """World points into the mover's body frame at each point's time."""
    inv = np.linalg.inv(mover.poses(times))
    return np.einsum("nab,nb->na", inv[:, :3, :3], points) + inv[:, :3, 3]


@pytest.fixture(scope="module")
def wall():
    world = wall_world(distance_m=10.0)
    return world, Trajectory(world, speed_variation=0.0, seed=3)


def test_a_boat_astern_is_seen_where_it_was_at_each_firing_so_the_seam_smears_it_by_speed_times_time(wall):
    world, traj = wall
    t0, speed = 20.0, 6.0  # the ASV is at x = 40 m doing 2 m/s; the box overtakes at 6 m/s, 12 m astern
    mover = box_boat(AlongRoute(world.route, station_m=28.0, time_s=t0, speed_mps=speed))
    scan = HDL32E(**EXACT).scan(Scene(world, Traffic((mover,))), traj, t0)
    label = scan.points["label"]
    on_box = label == len(world.parts)
    assert on_box.sum() > 300 and set(np.unique(label)) <= {0, 1, 2}
    times = t0 + scan.points["time"][on_box].astype(np.float64)
    pw = world_points(traj, scan)[on_box]
    body = in_body(mover, times, pw)
    # every point on the box surface where the box was at that ray's firing time
    np.testing.assert_allclose(np.max(np.abs(body - [0, 0, 1]) / HALF, axis=1), 1.0, atol=2e-4)
    # the bow face, towards the ASV: x = x_box(t) + half length, so the revolution seam (the start azimuth is astern)
    # shows it twice, displaced by the speed times the firing-time difference (~0.1 s: 0.6 m)
    bow = np.abs(body[:, 0] - HALF[0]) < 1e-3
    np.testing.assert_allclose(pw[bow, 0], 28.0 + speed * (times[bow] - t0) + HALF[0], atol=1e-3)
    assert np.ptp(pw[bow, 0]) == pytest.approx(speed * np.ptp(times[bow]), abs=1e-3) and np.ptp(pw[bow, 0]) > 0.5


def test_a_boat_between_the_sensor_and_a_wall_occludes_it_and_has_its_own_label_and_reflectivity(wall):
    world, traj = wall
    t0 = 20.0
    mover = box_boat(AlongRoute(world.route, station_m=47.0, time_s=t0, speed_mps=3.0, lateral_m=5.0))
    lidar = HDL32E(**EXACT, attenuation_per_m=0.0)
    static = lidar.scan(world, traj, t0)
    scan = lidar.scan(Scene(world, Traffic((mover,))), traj, t0)
    wall_label = [p.name for p in world.parts].index("wall")
    on_wall, on_box = scan.points["label"] == wall_label, scan.points["label"] == len(world.parts)
    assert (static.points["label"] == wall_label).sum() - on_wall.sum() > 500  # the shadow
    # no wall point was seen through the box as it was at that point's firing time
    times = t0 + scan.points["time"].astype(np.float64)
    origins = traj.lidar_poses(times)[:, :3, 3]
    pw = world_points(traj, scan)
    ranges = np.linalg.norm(pw - origins, axis=1)
    inv = np.linalg.inv(mover.poses(times[on_wall]))
    d = (pw[on_wall] - origins[on_wall]) / ranges[on_wall, None]
    t_box, _ = mover.cast(np.einsum("nab,nb->na", inv[:, :3, :3], origins[on_wall]) + inv[:, :3, 3], np.einsum("nab,nb->na", inv[:, :3, :3], d))
    assert (t_box > ranges[on_wall]).all()
    # intensity of the side facing the ASV (its normal -y): 100 * reflectivity * cos(incidence)
    body = in_body(mover, times[on_box], pw[on_box])
    side = (np.abs(body[:, 1] + HALF[1]) < 1e-3) & (np.abs(body[:, 0]) < HALF[0] - 0.01) & (np.abs(body[:, 2] - 1.0) < HALF[2] - 0.01)
    assert side.sum() > 200
    cos_inc = np.abs(pw[on_box][side, 1] - origins[on_box][side, 1]) / ranges[on_box][side]
    np.testing.assert_allclose(scan.points["intensity"][on_box][side], 100.0 * STEEL.reflectivity * cos_inc, rtol=1e-4)


def test_no_traffic_or_traffic_out_of_reach_leaves_the_scan_unchanged(wall):
    world, traj = wall
    lidar = HDL32E(seed=4)
    plain = lidar.scan(world, traj, 10.0)
    far = box_boat(AlongRoute(world.route, station_m=500.0, time_s=0.0, speed_mps=1.0))
    for scene in (Scene(world), Scene(world, Traffic((far,)))):
        assert np.array_equal(lidar.scan(scene, traj, 10.0).points, plain.points)


@dataclass(frozen=True)
class Parked:
    """A mover that stays at one pose."""

    pose: np.ndarray

    def poses(self, ts):
        return np.repeat(self.pose[None], len(ts), axis=0)


def test_a_barge_wheelhouse_blocks_the_satellite_behind_it():
    world, antenna_at = open_water(), Static()
    clear = GnssReceiver(seed=1, noise=NOISE_OFF).fix(world, antenna_at, 1.0)
    sat = min((s for s in clear.sats if 20.0 < s.el_deg < 40.0), key=lambda s: s.el_deg)
    truth = {s.prn: s for s in clear.truth.sats}
    assert truth[sat.prn].los
    # the wheelhouse (body x = -12 m, 6 m wide, 1.5..7.5 m high) 9 m away in the satellite's azimuth, side on
    az = np.deg2rad(sat.az_deg)
    towards = np.array([np.sin(az), np.cos(az)])  # ENU from azimuth (clockwise from north)
    yaw = np.arctan2(towards[1], towards[0]) + np.pi / 2
    wheelhouse = 9.0 * towards
    centre = wheelhouse - (-12.0) * np.array([np.cos(yaw), np.sin(yaw)])
    barge, material = boat("barge")
    mover = Mover("barge", barge, material, Parked(level_poses(centre[None], np.array([yaw]))[0]))
    blocked = GnssReceiver(seed=1, noise=NOISE_OFF).fix(Scene(world, Traffic((mover,))), antenna_at, 1.0)
    after = {s.prn: s for s in blocked.truth.sats}
    assert not after[sat.prn].los
    assert sum(s.los for s in after.values()) < sum(s.los for s in truth.values())


class Recording:
    """An ASV trajectory that remembers the latest time it was asked about."""

    def __init__(self, trajectory):
        self.trajectory, self.latest = trajectory, -np.inf

    def poses(self, ts):
        self.latest = max(self.latest, float(np.max(ts)))
        return self.trajectory.poses(ts)


def test_chase_boat_follows_at_distance_and_offset_and_never_asks_the_future(wall):
    world, traj = wall
    asv = Recording(traj)
    chase = Chase(asv, distance_m=15.0, lateral_m=-6.0, lag_s=2.0)
    t = np.array([10.0, 30.0])
    pose = chase.poses(t)
    assert asv.latest <= t.max()
    expected = traj.poses(t - 2.0)[:, :2, 3] + [-15.0, -6.0]  # route along +x: behind is -x, right is -y
    np.testing.assert_allclose(pose[:, :2, 3], expected, atol=1e-9)
    lidar, recorder = HDL32E(), Recording(traj)
    lidar.scan(Scene(world, Traffic((box_boat(Chase(recorder, 15.0, -6.0)),))), traj, 30.0)
    assert recorder.latest <= 30.0 + lidar.revolution_s + 1e-9


def test_crossing_and_oncoming_kinematics(wall):
    world, traj = wall
    config = TrafficConfig(
        movers=[
            {"kind": "crossing", "station_m": 100.0, "time_s": 10.0, "speed_mps": 4.0},
            {"kind": "along", "station_m": 200.0, "time_s": 10.0, "speed_mps": 5.0, "oncoming": True, "lateral_m": 20.0},
        ]
    )
    traffic = build_traffic(config, world, traj)
    assert traffic.ids == ["crossing_0", "along_1"]
    poses = traffic.poses([10.0, 12.0, 1000.0])
    np.testing.assert_allclose(poses[0, :2, :2, 3], [[100.0, 0.0], [100.0, 8.0]], atol=1e-9)  # 90 deg: to the left bank
    land = 50.0 - (5.0 + BOATS["cruiser"][0].length_m / 2)  # route bank distance 50 m less the landing margin
    np.testing.assert_allclose(poses[0, 2, :2, 3], [100.0, land], atol=1e-9)
    np.testing.assert_allclose(poses[1, :2, :2, 3], [[200.0, 20.0], [190.0, 20.0]], atol=1e-9)
    assert poses[1, 0, 0, 0] == pytest.approx(-1.0)  # heading down the route


def test_traffic_config_names_movers_and_rejects_bad_input():
    assert TrafficConfig().movers == []
    with pytest.raises(ValidationError, match="used twice"):
        TrafficConfig(movers=[{"kind": "chase", "id": "a"}, {"kind": "chase", "id": "a"}])
    with pytest.raises(ValidationError, match="distance_m"):
        TrafficConfig(movers=[{"kind": "chase", "distance_m": -1.0}])
    with pytest.raises(ValidationError, match="boat"):
        TrafficConfig(movers=[{"kind": "chase", "boat": "liner"}])
    with pytest.raises(ValidationError, match="kind"):
        TrafficConfig(movers=[{"kind": "submarine"}])
    for kind in BOATS:
        mesh, _ = boat(kind)
        assert mesh.is_watertight


def test_scenarios_without_traffic_keep_their_hash_and_a_bad_mover_names_its_key():
    plain = scenarios.load("harvard_beam_bridge")
    assert plain.traffic is None and "traffic" not in plain.resolved()
    assert scenarios.load("harvard_beam_bridge", set=["traffic.movers=[]"]).traffic.movers == []
    with pytest.raises(ValueError, match=r"traffic\.movers.*distance_m"):
        scenarios.load("chase_boat", set=["traffic.movers.chase.distance_m=-1.0"])


def test_a_run_with_traffic_records_the_movers_at_scan_times_and_their_points(tmp_path):
    scenario = scenarios.load("chase_boat", set=["stretch={start_s = 1580.0, end_s = 1581.5}"])
    result = scenarios.run(scenario, tmp_path / "run", workers=1, report=False)
    with open(result.out_dir / "movers.csv") as handle:
        rows = list(csv.DictReader(handle))
    truth = files.read_tum(result.out_dir / "groundtruth.tum", scenario_time=True)
    assert [float(r["t"]) for r in rows] == pytest.approx(truth[:, 0], abs=1e-3) and {r["id"] for r in rows} == {"chase"}
    world = worlds.load(scenario.world, **scenario.world_params)
    assert {int(r["label"]) for r in rows} == {len(world.parts)}
    yaw = np.radians([float(r["yaw_deg"]) for r in rows])
    behind = truth[:, 1:3] - 15.0 * np.c_[np.cos(yaw), np.sin(yaw)] - 6.0 * np.c_[-np.sin(yaw), np.cos(yaw)]
    np.testing.assert_allclose(np.c_[[float(r["x"]) for r in rows], [float(r["y"]) for r in rows]], behind, atol=2e-3)
    points = result.metrics["run"]["mover_points"]
    assert points["median"] > 50 and points["scans_with"] == 1.0


def test_a_steel_wheelhouse_side_reflects_by_the_image_method_and_fibreglass_does_not():
    barge = Mover("barge", *boat("barge"), Parked(np.eye(4)))
    el = np.deg2rad(20.0)
    north = np.array([[0.0, np.cos(el), np.sin(el)]])
    antenna = np.array([-12.0, 13.0, 2.0])  # 10 m off the wheelhouse's side (body y = 3 m, x -14..-10, z 1.5..7.5)
    found = barge.reflections(np.eye(4), antenna, north, radius_m=200.0)
    assert len(found) == 1
    assert found.extra_m[0] == pytest.approx(2 * 10.0 * np.cos(el))
    np.testing.assert_allclose(found.point[0], [-12.0, 3.0, 2.0 + 10.0 * np.tan(el)], atol=1e-9)
    runabout = Mover("runabout", *boat("runabout"), Parked(np.eye(4)))
    assert len(runabout.reflections(np.eye(4), np.array([0.0, 5.0, 1.0]), north, radius_m=200.0)) == 0
