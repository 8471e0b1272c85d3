"""gicp's scene-carried voxel grid (matcher.scene_grid, `voxel_grid = "scene"`): the same world points seen from two
poses are downsampled to the same world points when the second scan's grid is carried by the exact motion, and not when
the grid is fixed to the sensor (the aliasing that reads as motion); with an identity grid it is small_gicp's own
preprocess_points (to the last bits); under charles_river's lock road it removes the sensor grid's along-track bias
against the exact truth."""

from __future__ import annotations

import numpy as np
import pytest
import small_gicp
from hypothesis import given
from hypothesis import strategies as st

import matcher
from matcher.motion import se3_exp
from matcher.scene_grid import carried, downsample
from scenarios.pipeline.assembly import assemble
from scenarios.pipeline.stream import scan_times
from scenarios.spec.library import validate

VOXEL_M = 0.3


def _world_points(seed: int) -> np.ndarray:
    """Points on three walls and a deck around the origin, as a canal with a bridge would give (the planes off the
    voxel boundaries, where rounding alone would move a point between two cells)."""
    rng = np.random.default_rng(seed)
    n = 1500
    along = rng.uniform(-20.0, 20.0, (4, n))
    up = rng.uniform(-1.0, 5.0, (4, n))
    walls = [
        np.c_[along[0], np.full(n, 8.13), up[0]],
        np.c_[along[1], np.full(n, -7.91), up[1]],
        np.c_[np.full(n, 15.04), 0.8 * along[2], up[2]],
        np.c_[along[3], 0.4 * along[3] + rng.uniform(-8.0, 8.0, n) * 0.9, np.full(n, 6.07)],
    ]
    return np.concatenate(walls)


def _in_world(points: small_gicp.PointCloud, pose: np.ndarray) -> np.ndarray:
    return points.points()[:, :3] @ pose[:3, :3].T + pose[:3, 3]


def _sorted(xyz: np.ndarray) -> np.ndarray:
    return xyz[np.lexsort(np.round(xyz, 6).T)]


def test_an_identity_grid_is_small_gicps_preprocess_points():
    xyz = _world_points(0)
    theirs, _ = small_gicp.preprocess_points(xyz, downsampling_resolution=VOXEL_M, num_neighbors=12, num_threads=1)
    ours, _ = downsample(xyz, np.eye(4), VOXEL_M, 12, 1)
    # the same voxels in the same order; the centroids agree to the last bits (the matrix products round differently)
    assert np.allclose(theirs.points(), ours.points(), rtol=0.0, atol=1e-12)
    assert np.allclose(np.asarray(theirs.normals()), np.asarray(ours.normals()), rtol=0.0, atol=1e-9)
    assert np.allclose(np.asarray(theirs.covs()), np.asarray(ours.covs()), rtol=0.0, atol=1e-9)


@given(
    st.floats(0.01, 0.9),
    st.floats(-0.2, 0.2),
    st.floats(-0.2, 0.2),
    st.floats(-0.05, 0.05),
    st.integers(0, 3),
)
def test_the_same_world_points_from_two_poses_downsample_alike_on_the_carried_grid(forward, left, up, yaw, seed):
    world = _world_points(seed)
    first = np.eye(4)
    motion = se3_exp(np.array([forward, left, up, 0.0, 0.0, yaw]))  # second scan's frame in the first's
    second = first @ motion
    seen_first = (world - first[:3, 3]) @ first[:3, :3]
    seen_second = (world - second[:3, 3]) @ second[:3, :3]

    grid_first = np.eye(4)
    a, _ = downsample(seen_first, grid_first, VOXEL_M, 12, 1)
    b, _ = downsample(seen_second, carried(grid_first, motion, VOXEL_M), VOXEL_M, 12, 1)
    assert np.allclose(_sorted(_in_world(a, first)), _sorted(_in_world(b, second)), atol=1e-6)


def test_on_a_grid_fixed_to_the_sensor_a_quarter_voxel_of_motion_moves_the_centroids():
    world = _world_points(0)
    motion = se3_exp(np.array([0.25, 0.0, 0.0, 0.0, 0.0, 0.0]))  # one revolution at 2.5 m/s
    a, _ = downsample(world, np.eye(4), VOXEL_M, 12, 1)
    b, _ = downsample(world - motion[:3, 3], np.eye(4), VOXEL_M, 12, 1)
    first, second = _in_world(a, np.eye(4)), _in_world(b, motion)
    nearest = np.min(np.linalg.norm(second[:, None, :] - first[None, ::7, :], axis=2), axis=1)
    assert np.median(nearest) > 0.01  # carried with the scene, they coincide (the test above)


@given(st.integers(-50, 50), st.integers(-50, 50), st.integers(-5, 5))
def test_the_carried_translation_is_reduced_modulo_the_voxel_without_moving_a_cell(i, j, k):
    motion = se3_exp(np.array([i * VOXEL_M + 0.1, j * VOXEL_M + 0.05, k * VOXEL_M, 0.0, 0.0, 0.2]))
    grid = carried(np.eye(4), motion, VOXEL_M)
    assert np.all((grid[:3, 3] >= 0.0) & (grid[:3, 3] < VOXEL_M + 1e-12))
    xyz = _world_points(1)
    reduced, _ = downsample(xyz, grid, VOXEL_M, 12, 1)
    full, _ = downsample(xyz, motion, VOXEL_M, 12, 1)
    assert np.allclose(_sorted(reduced.points()[:, :3]), _sorted(full.points()[:, :3]), atol=1e-6)


@pytest.fixture(scope="module")
def lock_road():
    """40 revolutions under charles_river's lock road (4715-4760 m, seed 0), where flat walls and the deck leave few
    edges along the route: the scans and the exact trajectory."""
    scenario = validate({"name": "lock_road", "world": "charles_river", "seed": 0, "stretch": {"start_m": 4715.0, "end_m": 4760.0}, "estimators": []})
    stack = assemble(scenario)
    stamps = scan_times(stack.lidar, stack.t_start, stack.t_end)[100:140]
    world = stack.vessel_run.world
    return [stack.lidar.scan(world, stack.trajectory, float(t)) for t in stamps], stack.trajectory


def _forward_step_errors(scans, trajectory, grid: str) -> np.ndarray:
    # scan to scan, where each step is one registration and carries the grid's aliasing whole; against gicp's default
    # keyframe the steps are differences of registrations against one keyframe, which share much of it (median +17 mm)
    m = matcher.create("gicp", voxel_grid=grid, keyframe_m=0.0)
    errors = []
    for scan in scans:
        r = m.register(scan)
        if r.ok and r.info.get("ref_stamp") is not None:
            truth = np.linalg.solve(trajectory.lidar_pose(float(r.info["ref_stamp"])), trajectory.lidar_pose(scan.stamp))
            errors.append(r.T[0, 3] - truth[0, 3])
    return np.array(errors)


def test_under_the_lock_road_the_scene_grid_removes_the_sensor_grids_along_track_bias(lock_road):
    sensor, scene = (_forward_step_errors(*lock_road, grid) for grid in ("sensor", "scene"))
    assert len(scene) >= 35 and len(sensor) >= 35
    assert np.median(sensor) > 0.02  # over-read by the sensor-fixed grid's aliasing (+39 mm at 48b754d)
    assert abs(np.median(scene)) < 0.005 and scene.std() < 0.5 * sensor.std()
