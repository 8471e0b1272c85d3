"""HDL-32E realism against analytic cases: detection probability by reflectivity and range, mixed pixels
at a depth edge (sim.beam), near-range blanking, and materials that must exist."""

import numpy as np
import open3d as o3d
import pytest
import trimesh
from analytic_worlds import ORIGIN, box, ground_world, straight_route, wall_world, water
from hypothesis import given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import worlds
from scenarios.cli import app
from sim.beam import edge_rays, footprint_offsets, mix
from sim.lidar import HDL32E, detection_constant, detection_probability
from sim.trajectory import Trajectory
from worlds.materials import CONCRETE, Material
from worlds.world import Part, World

QUIET = dict(range_noise_m=0.0, range_resolution_m=0.0, dropout_rate=0.0)
DARK = Material("dark", reflectivity=0.02, gnss_reflective=False)


def to_world(traj, scan):
    poses = traj.lidar_poses(scan.stamp + scan.points["time"].astype(np.float64))
    return np.einsum("nab,nb->na", poses[:, :3, :3], scan.xyz) + poses[:, :3, 3]


# --- detection probability ------------------------------------------------------------------------


@given(
    rho=st.floats(0.01, 1.0),
    cos=st.floats(0.05, 1.0),
    r=st.floats(1.0, 99.0),
    dr=st.floats(0.1, 50.0),
    r10=st.floats(20.0, 150.0),
)
def test_detection_probability_falls_with_range_and_rises_with_reflectivity(rho, cos, r, dr, r10):
    k = detection_constant(r10)
    near, far = detection_probability(rho * cos / r**2, k), detection_probability(rho * cos / (r + dr) ** 2, k)
    assert 0.0 <= far <= near <= 1.0
    assert detection_probability(min(1.0, 2 * rho) * cos / r**2, k) >= near


def test_detection_probability_meets_the_datasheet_ranges():
    k = detection_constant(70.0)
    assert detection_probability(0.10 / 70.0**2, k) == pytest.approx(0.9)
    assert detection_probability(0.20 / 99.0**2, k) == pytest.approx(0.9, abs=0.01)  # datasheet: 80-100 m range
    assert detection_probability(0.20 / 99.0**2, k, dropout_rate=0.5) == pytest.approx(0.45, abs=0.01)


@pytest.mark.parametrize("distance_m", [40.0, 60.0, 80.0])
def test_returns_from_a_dark_wall_follow_the_detection_formula(distance_m):
    """A 2%-reflective wall: the share of its rays that return matches 1 - exp(-k rho cos / r^2) ray by ray."""
    world = wall_world(distance_m=distance_m, height_m=30.0, material=DARK)
    traj = Trajectory(world)
    lidar = HDL32E(**QUIET, beam_divergence_mrad=0.0)
    observed, expected, variance = 0, 0.0, 0.0
    for t0 in (1.0, 2.0, 3.0):
        rays = lidar.rays(traj, t0)
        hit = world.raycasting_scene.cast_rays(o3d.core.Tensor(rays))
        t, prim = hit["t_hit"].numpy(), hit["primitive_ids"].numpy()
        on_wall = np.isfinite(t) & (t <= 100.0)
        on_wall[on_wall] &= world.face_part[prim[on_wall]] == 1
        cos = np.abs(np.einsum("ij,ij->i", hit["primitive_normals"].numpy()[on_wall], rays[on_wall, 3:]))
        p = detection_probability(DARK.reflectivity * cos / t[on_wall].astype(np.float64) ** 2, detection_constant(70.0))
        expected, variance = expected + p.sum(), variance + (p * (1 - p)).sum()
        observed += int((lidar.scan(world, traj, t0).points["label"] == 1).sum())
    assert abs(observed - expected) < 5 * np.sqrt(variance) + 1, (observed, expected)


def test_detected_share_of_a_dark_wall_falls_with_its_distance():
    shares = []
    for d in (30.0, 50.0, 70.0, 90.0):
        world = wall_world(distance_m=d, height_m=40.0, material=DARK)
        points = HDL32E(**QUIET, beam_divergence_mrad=0.0).scan(world, Trajectory(world), 1.0).points
        bright = HDL32E(**QUIET, beam_divergence_mrad=0.0, range_10pct_m=1e4).scan(world, Trajectory(world), 1.0).points
        shares.append((points["label"] == 1).sum() / max((bright["label"] == 1).sum(), 1))
    assert all(a > b for a, b in zip(shares, shares[1:], strict=False)), shares
    assert shares[0] > 2 * shares[-1]


# --- mixed pixels ---------------------------------------------------------------------------------

NEAR_X, FAR_X = 20.0, 40.0


def edge_world() -> World:
    """A panel across the route's left half (face x = 20, y from 0 to 60: its edge is the line x = 20, y = 0)
    in front of a wall (face x = 40) across everything."""
    panel = box((1.0, 60.0, 40.0), (NEAR_X + 0.5, 30.0, 10.0))
    back = box((1.0, 400.0, 40.0), (FAR_X + 0.5, 0.0, 10.0))
    parts = [water(), Part("panel", "wall", CONCRETE, panel), Part("back", "wall", CONCRETE, back)]
    return World("edge", parts, straight_route(10.0), ORIGIN)


@pytest.fixture(scope="module")
def edge():
    world = edge_world()
    traj = Trajectory(world, speed_mps=0.5)
    return world, traj


def test_a_straddled_edge_gives_intermediate_ranges_only_at_the_edge(edge):
    world, traj = edge
    lidar = HDL32E(**QUIET)
    n_between = 0
    for t0 in np.arange(1.0, 7.0):  # the edge falls at another place between two rays in each revolution
        scan = lidar.scan(world, traj, float(t0))
        pw = to_world(traj, scan)
        origin = traj.lidar_poses(scan.stamp + scan.points["time"].astype(np.float64))[:, :3, 3]
        bearing_point = np.arctan2(pw[:, 1] - origin[:, 1], pw[:, 0] - origin[:, 0])
        ahead = np.abs(bearing_point) < 0.5  # the sector of the edge at y = 0 (the panel's far end is at 71 deg)
        solid = (scan.points["label"] > 0) & ahead
        between = solid & (pw[:, 0] > NEAR_X + 0.01) & (pw[:, 0] < FAR_X - 0.01)
        n_between += int(between.sum())
        # each lies on a ray within half a divergence plus an azimuth step of the edge's bearing
        bearing_edge = np.arctan2(0.0 - origin[:, 1], NEAR_X - origin[:, 0])
        off = np.abs(bearing_point - bearing_edge)[between]
        assert (off < 0.5 * 3.3e-3 + np.deg2rad(lidar.azimuth_step_deg)).all()
        # away from the edge, points lie on the panel or on the back wall exactly
        rest = solid & ~between
        assert np.minimum(np.abs(pw[rest, 0] - NEAR_X), np.abs(pw[rest, 0] - FAR_X)).max() < 1e-3
    # 12 lasers see the edge (the others hit the water first); 3 samples over the 3.3 mrad strip catch an edge
    # in 2.2 of every 2.9 mrad between two rays (the lasers of one firing see it at nearly the same place)
    assert n_between >= 20


def test_a_pencil_beam_has_no_mixed_pixels(edge):
    world, traj = edge
    scan = HDL32E(**QUIET, beam_divergence_mrad=0.0).scan(world, traj, 2.0)
    pw = to_world(traj, scan)[scan.points["label"] > 0]
    assert np.minimum(np.abs(pw[:, 0] - NEAR_X), np.abs(pw[:, 0] - FAR_X)).max() < 1e-3


@given(near=st.floats(1.0, 90.0), gap=st.one_of(st.just(0.0), st.floats(0.01, 50.0)), share=st.integers(1, 2))
def test_a_mixed_range_lies_between_the_two_surfaces(near, gap, share):
    """Three footprint samples, `share` of them on the near surface: the range is between both, nearer the
    stronger part, and the label is the strongest sample's."""
    far = near + gap
    t = np.array([[near] * share + [far] * (3 - share)])
    power = np.array([[0.3 / near**2] * share + [0.3 / far**2] * (3 - share)])
    mean_power, r, strongest = mix(t, power)
    assert near - 1e-9 <= r[0] <= far + 1e-9
    assert mean_power[0] == pytest.approx(power.mean())
    if share == 2 and gap > 0:
        assert r[0] < (near + far) / 2 and strongest[0] < 2


def test_a_sample_on_nothing_keeps_the_range_and_lowers_the_power():
    mean_power, r, _ = mix(np.array([[10.0, 10.0, np.inf]]), np.array([[0.003, 0.003, 0.0]]))
    assert r[0] == pytest.approx(10.0) and mean_power[0] == pytest.approx(0.002)


@settings(max_examples=50)
@given(ranges=st.lists(st.floats(1.0, 100.0), min_size=8, max_size=8), slope=st.floats(-2.0, 2.0))
def test_a_smooth_sweep_has_no_edges_and_a_step_has_two(ranges, slope):
    r = (20.0 + slope * np.arange(8))[:, None] * np.ones((1, 32))
    assert not edge_rays(r, np.ones_like(r, dtype=bool), 0.2).any()
    r[4:] += 5.0
    edges = edge_rays(r, np.ones_like(r, dtype=bool), 0.2)
    assert edges[3].all() and edges[4].all() and edges.sum() == 64


def test_footprint_samples_split_the_strip_evenly():
    np.testing.assert_allclose(footprint_offsets(3.3e-3, 3), [-1.1e-3, 1.1e-3])
    np.testing.assert_allclose(footprint_offsets(3.0e-3, 5), [-1.2e-3, -0.6e-3, 0.6e-3, 1.2e-3])


# --- near-range blanking ----------------------------------------------------------------------------


@settings(max_examples=10, deadline=None)
@given(min_range=st.floats(1.0, 8.0), noise=st.floats(0.0, 0.05))
def test_nothing_is_reported_under_the_blanking_range(min_range, noise):
    """Dry ground all round: the lowest lasers hit it from 3.5 m on; nothing closer than min_range comes back."""
    world = ground_world()
    scan = HDL32E(range_noise_m=noise, min_range_m=min_range).scan(world, Trajectory(world), 1.0)
    r = np.linalg.norm(scan.xyz, axis=1)
    assert r.min() >= min_range - 1e-4
    assert len(scan) > 10_000


# --- materials ------------------------------------------------------------------------------------


def test_an_unknown_material_in_a_mesh_file_is_one_line_naming_it(tmp_path):
    path = tmp_path / "quay.ply"
    trimesh.creation.box(extents=(100.0, 4.0, 3.0)).export(path)
    with pytest.raises(ValueError, match="unknown material 'unobtainium'"):
        worlds.load(str(path), material="unobtainium")
    spec = tmp_path / "s.toml"
    spec.write_text(f'name = "s"\nworld = "{path}"\n[world_params]\nmaterial = "unobtainium"\n')
    result = CliRunner().invoke(app, ["run", str(spec), "--out", str(tmp_path / "out"), "--quiet"])
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2 and len(lines) == 1 and "unobtainium" in lines[0], result.output
    assert not (tmp_path / "out").exists()


def test_every_face_carries_its_parts_reflectivity():
    world = edge_world()
    for i, part in enumerate(world.parts):
        faces = world.face_part == i
        assert (world.face_reflectivity[faces] == np.float32(part.material.reflectivity)).all()
        assert (world.face_is_water[faces] == part.material.water).all()
