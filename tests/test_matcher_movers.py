"""Boats under way in the scans (matcher.movers): a cruiser oncoming through the next span and a runabout overtaking,
as busy_waterway's Harvard Bridge stretch has them, while the vessel passes under a beam bridge whose deck and walls
leave the motion along the route to the piers. Against exact truth: gicp's chained heading and forward motion, with the
movers screen and without it; the screen's verdicts on exact planes; and a static world where it drops nothing."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

import matcher
import sim
from matcher.motion import SPEED_WALK_MPS_PER_SQRT_S, ConstantVelocity
from matcher.movers import MoverTest, moving_objects
from tests.beam_bridge import beam_bridge_river

STATION_M = 200.0
TEST = MoverTest(min_speed_mps=1.0, link_m=2.0, max_extent_m=60.0, max_m=1.0)


@pytest.fixture(scope="module")
def static_scene():
    world = beam_bridge_river(STATION_M)
    return world, sim.Trajectory(world, start_m=STATION_M - 30.0, speed_mps=2.3, speed_variation=0.0)


@pytest.fixture(scope="module")
def scene(static_scene):
    world, trajectory = static_scene
    movers = [
        {"kind": "along", "boat": "cruiser", "station_m": STATION_M + 25.0, "time_s": 0.0, "speed_mps": 4.0, "oncoming": True, "lateral_m": 12.0},
        {"kind": "along", "boat": "runabout", "station_m": STATION_M - 45.0, "time_s": 0.0, "speed_mps": 5.0, "lateral_m": -7.0},
    ]
    traffic = sim.build_traffic(sim.TrafficConfig(movers=movers), world, trajectory)
    return sim.Scene(world, traffic), trajectory


def _chain(scene, trajectory, seconds: float = 8.0, **params) -> tuple[float, float, float]:
    """(worst chained yaw error in deg, median matched/true forward motion, median share of points dropped as moving on
    their own, beside those the co-moving screen drops) of gicp over `seconds` of the passage."""
    lidar = sim.HDL32E(seed=5)
    m = matcher.create("gicp", **{"drop_movers": True, **params})
    chained, truth0 = np.eye(4), None
    yaw_errors, ratios, dropped = [], [], []
    for k in range(int(seconds / lidar.revolution_s)):
        t = k * lidar.revolution_s
        r = m.register(lidar.scan(scene, trajectory, t))
        if truth0 is None:
            truth0 = trajectory.lidar_pose(t)
            continue
        assert r.ok, r.info.get("reason")
        chained = chained @ r.T
        true_rel = np.linalg.inv(trajectory.lidar_pose(r.info["ref_stamp"])) @ trajectory.lidar_pose(t)
        true_chain = np.linalg.inv(truth0) @ trajectory.lidar_pose(t)
        d = np.linalg.inv(true_chain) @ chained
        yaw_errors.append(abs(np.degrees(np.arctan2(d[1, 0], d[0, 0]))))
        ratios.append(r.T[0, 3] / true_rel[0, 3])
        dropped.append((r.info["moving_points"] - r.info["comoving_points"]) / r.n_points)
    return max(yaw_errors), float(np.median(ratios)), float(np.median(dropped))


def test_boats_under_way_are_dropped_and_the_heading_kept(scene):
    yaw, ratio, dropped = _chain(*scene)
    assert yaw < 0.5
    assert abs(ratio - 1.0) < 0.05
    assert dropped > 0.005


def test_without_the_screen_the_boats_turn_the_heading(scene):
    yaw_kept, _, _ = _chain(*scene)
    yaw, _, _ = _chain(*scene, drop_movers=False)
    assert yaw > 2.0 * yaw_kept


def test_in_a_static_world_nothing_moves_on_its_own(static_scene):
    yaw, ratio, dropped = _chain(*static_scene)
    assert yaw < 0.5 and abs(ratio - 1.0) < 0.05
    assert dropped == 0.0


def _planes(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Points and normals of a static scene: a quay wall along x at y = 15, a pier face across x at x = 23 (4 m wide),
    in the reference's frame, 0.3 m apart."""
    s = np.arange(-30.0, 30.0, 0.3)
    z = np.arange(0.0, 3.0, 0.3)
    wall = np.array([(x, 15.0, h) for x in s for h in z])
    pier = np.array([(23.0, y, h) for y in np.arange(-2.0, 2.0, 0.3) for h in z])
    points = np.vstack([wall, pier]) + rng.normal(0.0, 0.005, (len(wall) + len(pier), 3))
    normals = np.vstack([np.tile([0.0, -1.0, 0.0], (len(wall), 1)), np.tile([-1.0, 0.0, 0.0], (len(pier), 1))])
    return points, normals


BOW_POINTS = 9 * 7


def _hull(at: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A 6 m box hull's two faces seen by the sensor, 0.3 m apart: its side (normal -y) and its bow (normal -x)."""
    xs, zs = np.arange(0.0, 6.0, 0.3), np.arange(0.0, 2.0, 0.3)
    side = np.array([(at[0] + x, at[1], z) for x in xs for z in zs])
    bow = np.array([(at[0], at[1] + y, z) for y in np.arange(0.0, 2.5, 0.3) for z in zs])
    normals = np.vstack([np.tile([0.0, -1.0, 0.0], (len(side), 1)), np.tile([-1.0, 0.0, 0.0], (len(bow), 1))])
    return np.vstack([side, bow]), normals


def _verdict(hull_step: np.ndarray, prior_cov: np.ndarray | None, pier_beside: bool = False) -> tuple[np.ndarray, int]:
    """The screen's mask on a new scan of the static planes and the hull moved by hull_step (the prior exact, the
    vessel at rest), and how many of the new scan's points are the hull's (they come last)."""
    rng = np.random.default_rng(1)
    static, static_normals = _planes(rng)
    hull_at = np.array([12.5, -1.0]) if pier_beside else np.array([5.0, 5.0])  # beside: its stern 4 m short of the pier (objects join within 2-4 m)
    hull, hull_normals = _hull(hull_at)
    ref = np.vstack([static, hull])
    ref_normals = np.vstack([static_normals, hull_normals])
    new = np.vstack([static + rng.normal(0.0, 0.005, static.shape), hull + np.append(hull_step, 0.0)])
    mask = moving_objects(new, np.eye(4), prior_cov, 0.1, ref, ref_normals, cKDTree(ref), 0.3, TEST)
    return mask, len(hull)


def test_a_hull_moving_on_its_own_is_dropped_and_the_planes_kept():
    mask, n_hull = _verdict(np.array([0.4, 0.0]), np.eye(3) * 1e-4)
    bow = mask[-BOW_POINTS:]  # the bow measures the motion along x; the side, parallel to it, fits both and is kept
    assert bow.mean() > 0.6
    assert not mask[:-n_hull].any()


def test_a_hull_slower_than_the_threshold_is_kept():
    mask, _ = _verdict(np.array([0.05, 0.0]), np.eye(3) * 1e-4)
    assert not mask.any()


def test_a_direction_the_prior_does_not_know_is_not_judged():
    unknown_x = np.diag([1.0, 1e-4, 1e-4])  # the last match left x unmeasured (a degenerate match's "unknown")
    mask, _ = _verdict(np.array([0.4, 0.0]), unknown_x)
    assert not mask.any()
    mask, n_hull = _verdict(np.array([0.0, 0.4]), unknown_x)  # across: the side measures it
    assert mask[-n_hull:].any()


def test_without_a_prior_covariance_nothing_is_judged():
    mask, _ = _verdict(np.array([0.4, 0.0]), None)
    assert not mask.any()


def test_a_pier_a_hull_passes_is_kept():
    mask, n_hull = _verdict(np.array([0.4, 0.0]), np.eye(3) * 1e-4, pier_beside=True)
    assert mask[-n_hull:].any()
    rng = np.random.default_rng(1)
    static, _ = _planes(rng)
    pier = static[:, 0] > 19.5
    assert not mask[: len(static)][pier].any()


def test_the_prior_covariance_keeps_what_a_degenerate_match_did_not_measure():
    cv = ConstantVelocity()
    step = np.eye(4)
    step[0, 3] = 0.2
    cv.update(step, 0.1, np.diag([1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6]))
    known = cv.translation_cov(0.1)[0, 0]
    cv.update(step, 0.1, np.diag([1.0, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6]))  # x unknown this time: the prior was kept there
    after = cv.translation_cov(0.1)[0, 0]
    walk = SPEED_WALK_MPS_PER_SQRT_S**2 * 0.1 * 0.1**2  # one revolution's walk, as a translation variance
    assert known < after < known + 2.5 * walk + 1e-9
    cv.update(step, 0.1, np.diag([np.nan] * 6))  # a plugin's covariance may be anything
    assert cv.translation_cov(0.1) is None
    cv.update(step, 0.1, np.zeros((6, 6)))
    assert cv.translation_cov(0.1) is None
