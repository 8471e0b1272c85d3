"""The closed loop against exact geometry: hull clearance to a wall at a known distance, a collision
that ends the loop as an outcome, the autopilot on a bend, and `[control]` in a scenario run."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from analytic_worlds import ORIGIN, wall_world, water

import scenarios
import sim
from scenarios.pipeline.closed_loop import ClosedLoop
from scenarios.score.vessel_log import VesselWatch
from sim.autopilot import Autopilot
from sim.clearance import HullClearance
from sim.driven_trajectory import DrivenTrajectory
from sim.dynamics import WamvDynamics
from sim.trajectory import TrajectoryConfig
from sim.vessel import HullConfig, hull_mesh
from worlds.route import Route
from worlds.world import World

HULL = hull_mesh(HullConfig(), mast_top_m=0.0)


def pose(x: float, y: float, yaw: float) -> np.ndarray:
    out = np.eye(4)
    out[:2, :2] = [[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]
    out[:2, 3] = x, y
    return out


@pytest.mark.parametrize("distance", [4.0, 10.0])
def test_clearance_to_a_wall_is_its_distance_minus_half_the_beam(distance):
    world = wall_world(distance_m=distance)
    clearance = HullClearance(world, HULL).at(pose(50.0, 0.0, 0.0))[0]
    assert clearance.distance_m == pytest.approx(distance - 1.2, abs=1e-4)
    assert world.parts[clearance.part].name == "wall"
    # turned bow-on the nearest point is the pontoons' bow corner, 2.45 m from base_link
    assert HullClearance(world, HULL).at(pose(50.0, 0.0, math.pi / 2))[0].distance_m == pytest.approx(distance - 2.45, abs=1e-4)


def test_an_overhead_deck_is_not_a_clearance_but_a_low_one_is():
    high = wall_world(distance_m=10.0)
    assert HullClearance(high, HULL).at(pose(50.0, 0.0, 0.0))[0].distance_m == pytest.approx(8.8, abs=1e-4)
    from analytic_worlds import box

    from worlds.materials import CONCRETE
    from worlds.world import Part

    deck = Part("deck", "bridge_deck", CONCRETE, box((20.0, 40.0, 1.0), (50.0, 0.0, 5.0)))  # underside 4.5 m up
    pier = Part("pier", "pier", CONCRETE, box((2.0, 2.0, 8.0), (50.0, -6.0, 2.0)))
    world = World("bridge", [water(), deck, pier], high.route, ORIGIN)
    c = HullClearance(world, HULL).at(pose(50.0, 0.0, 0.0))[0]
    assert world.parts[c.part].name == "pier" and c.distance_m == pytest.approx(6.0 - 1.0 - 1.2, abs=1e-4)


def drive_loop(world, start, commands_of, seconds, t_limit=1e9, end_station=1e9):
    config = TrajectoryConfig()
    traj = DrivenTrajectory(config, WamvDynamics(), start)
    lidar = sim.HDL32E(seed=1)
    receiver = sim.GnssReceiver(seed=1)
    watch = VesselWatch(world, traj, HullClearance(world, HULL), lidar.revolution_s)
    loop = ClosedLoop(world, traj, lidar, receiver, watch, 0.0, end_station, t_limit)
    events = []
    while not loop.done and loop.t < seconds:
        events += loop.step(commands_of(loop, traj))
    return loop, events


def test_steering_into_a_wall_ends_the_loop_at_the_first_contact():
    world = wall_world(distance_m=8.0)
    loop, events = drive_loop(world, (20.0, 0.0, 0.0, 2.0), lambda loop, traj: (0.4, 1.0), 60.0)
    log = loop.watch.log
    assert log.outcome == "collision" and loop.done
    assert log.contact.part == "wall" and log.contact.kind == "wall"
    touching = HullClearance(world, HULL).at(traj_pose := loop.trajectory.pose(log.contact.t))[0]
    assert touching.distance_m <= 0.05
    # 10 ms earlier the hull was still clear: the contact is found when it happens, not a revolution later
    assert HullClearance(world, HULL).at(loop.trajectory.pose(log.contact.t - 0.01))[0].distance_m > 0.0
    assert traj_pose[1, 3] > 4.0  # it did swing towards the wall
    assert all(e.stamp < log.contact.t for e in events)
    with pytest.raises(RuntimeError, match="ended"):
        loop.step((0.0, 0.0))


def test_the_loop_gives_each_revolution_then_its_fixes_in_time_order():
    world = wall_world(distance_m=30.0)
    loop, events = drive_loop(world, (20.0, 0.0, 0.0, 2.0), lambda loop, traj: (0.78, 0.78), 1.0)
    stamps = [e.stamp for e in events]
    assert stamps == sorted(stamps)
    kinds = [type(e).__name__ for e in events]
    assert kinds.count("ScanEvent") == 10 and kinds.count("FixEvent") == 5
    scan = next(e.scan for e in events if type(e).__name__ == "ScanEvent")
    wall = scan.points[scan.points["label"] == 1]
    assert len(wall) > 100  # the LiDAR sees the wall from the driven trajectory


def steer(route: Route, believed, seconds: float, start=(0.0, 0.0, 0.0, 2.0)) -> np.ndarray:
    """Drive the WAM-V model with the autopilot fed `believed(t, trajectory)` (no sensors); (N, 3) true x, y, yaw every 0.1 s."""
    pilot = Autopilot(route, WamvDynamics(), 2.0)
    traj = DrivenTrajectory(TrajectoryConfig(), WamvDynamics(), start)
    track = []
    for k in range(int(seconds / 0.1)):
        t = 0.1 * k
        traj.drive(pilot.commands(t, believed(t, traj)), t + 0.1)
        p = traj.pose(t + 0.1)
        track.append((p[0, 3], p[1, 3], math.atan2(p[1, 0], p[0, 0])))
    return np.array(track)


def bend_route() -> Route:
    """100 m straight along x, a 90-degree left bend of 80 m radius (about as tight as the Charles gets), 120 m straight north."""
    arc = np.linspace(0.0, np.pi / 2, 25)[1:]
    waypoints = np.vstack(
        [
            np.c_[np.linspace(0.0, 100.0, 21), np.zeros(21)],
            np.c_[100.0 + 80.0 * np.sin(arc), 80.0 - 80.0 * np.cos(arc)],
            np.c_[np.full(24, 180.0), np.linspace(85.0, 200.0, 24)],
        ]
    )
    return Route.from_waypoints(waypoints, 40.0, 40.0)


def test_the_autopilot_on_the_truth_follows_a_river_bend():
    route = bend_route()
    track = steer(route, lambda t, traj: traj.pose(t), 150.0)
    station, cross, _ = route.project(track[:, :2])
    assert np.abs(cross).max() < 2.0  # LOS cuts the bend's inside by about 1.3 m
    assert np.abs(cross[-300:]).max() < 0.6  # and settles on the straight after it
    assert station[-1] == pytest.approx(300.0, rel=0.03)  # 2 m/s held through the bend


def test_the_autopilot_steering_on_a_frozen_pose_holds_its_heading_and_leaves_the_bend():
    route = bend_route()
    frozen = pose(60.0, 0.0, 0.0)
    track = steer(route, lambda t, traj: frozen, 80.0, start=(60.0, 0.0, 0.0, 2.0))
    assert np.abs(track[:, 1]).max() < 0.5 and track[-1, 0] > 200.0  # straight on along x, out of the bend to the north


def test_a_closed_loop_scenario_run_writes_the_vessel_track_and_metrics(tmp_path):
    scenario = scenarios.load(
        "open_river",
        set=["stretch={start_m=100.0, end_m=130.0}", "control.mode=closed_loop", "control.steer_on=ekf", "expect=['vessel.min_clearance_m > 100']"],
    )
    result = scenarios.run(scenario, tmp_path / "run", workers=1, report=False)
    vessel = json.loads((tmp_path / "run" / "metrics.json").read_text())["vessel"]
    assert vessel["outcome"] == "completed" and vessel["completed"] == 1 and vessel["collisions"] == 0
    assert vessel["cross_track"]["max"] < 3.0 and vessel["distance_m"] == pytest.approx(30.0, abs=3.0)
    assert result.passed
    rows = (tmp_path / "run" / "vessel.csv").read_text().splitlines()
    assert rows[0].startswith("t,x,y,yaw_deg,station_m,cross_track_m,clearance_m") and len(rows) > 100
    assert 'steer_on = "ekf"' in (tmp_path / "run" / "scenario.toml").read_text()


def test_steering_on_an_unknown_estimator_is_a_one_line_error():
    with pytest.raises(ValueError, match="control.steer_on: no estimator with id 'kalman'"):
        scenarios.load("open_river", set=["control.mode=closed_loop", "control.steer_on=kalman"])


def test_a_closed_loop_scenario_exports_the_driven_motion(tmp_path):
    from scenarios.export.frames import open_stream

    scenario = scenarios.load(
        "open_river",
        set=[
            "stretch={start_m=100.0, end_m=110.0}",
            "control.mode=closed_loop",
            "control.current_enu_mps=[0.0, 0.5]",
            "matchers=[]",
            "estimators=[{id = 'gps_only', kind = 'gps_only'}]",
            "control.steer_on=gps_only",
            "expect=[]",
        ],
    )
    info, frames = open_stream(scenario)
    frames = list(frames)
    # steering on gps_only across the current, the drive's length follows the GPS error (consumer, synthetic sky: 47 scans;
    # SBAS, the real 2018 sky: 49); the closed loop itself stops at time_limit_factor x the open-loop time
    assert 40 <= len(frames) <= info.scans * scenario.control.time_limit_factor and all(len(f.scan.points) for f in frames)
    stamps = [f.stamp for f in frames]
    assert stamps == sorted(stamps)
    # a 0.5 m/s current across the route: the exported motion is the driven one, not the planned route
    import worlds

    route = worlds.load("open_river").route
    cross = route.project(np.array([f.base_pose[:2, 3] for f in frames]))[1]
    assert np.abs(cross).max() > 0.05
