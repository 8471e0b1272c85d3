"""Returns from tree crowns (sim.foliage): the chord a hit lies in, depths drawn from the crown's Beer-Lambert gap
probability (checked against scipy's truncated exponential), and scans whose crown echoes do not repeat from one
revolution to the next while a wall's do."""

import numpy as np
import pytest
import trimesh
from analytic_worlds import ORIGIN, box, straight_route, water
from scipy import stats

from sim.foliage import crown_echo_ranges
from sim.lidar import HDL32E
from sim.trajectory import Trajectory
from worlds.crowns import Crowns
from worlds.materials import CONCRETE, VEGETATION
from worlds.world import Part, World

QUIET = dict(range_noise_m=0.0, range_resolution_m=0.0, dropout_rate=0.0, beam_divergence_mrad=0.0)
CROWN_CENTRE, CROWN_RADIUS, EXTINCTION = np.array([30.0, 25.0, 6.0]), 5.0, 0.175


def one_crown() -> Crowns:
    return Crowns(CROWN_CENTRE[None], np.array([[CROWN_RADIUS, CROWN_RADIUS]]), np.array([EXTINCTION]))


def test_the_chord_holding_a_hit_is_the_crowns_analytic_one():
    crowns = Crowns(np.array([[20.0, 0.0, 5.0], [60.0, 0.0, 5.0]]), np.array([[3.0, 3.0], [4.0, 2.0]]), np.array([0.2, 0.3]))
    origins = np.tile([0.0, 0.0, 5.0], (4, 1))
    directions = np.tile([1.0, 0.0, 0.0], (4, 1))
    crown, entry, exit_ = crowns.chord_at(origins, directions, np.array([18.0, 23.0, 57.0, 40.0]))
    assert crown.tolist() == [0, 0, 1, -1]
    np.testing.assert_allclose(entry[:3], [17.0, 17.0, 56.0])
    np.testing.assert_allclose(exit_[:3], [23.0, 23.0, 64.0])


def test_a_sensor_inside_a_crown_starts_its_chord_at_zero():
    crown, entry, exit_ = one_crown().chord_at(CROWN_CENTRE[None], np.array([[0.0, 1.0, 0.0]]), np.array([2.0]))
    assert crown.tolist() == [0] and entry[0] == 0.0 and exit_[0] == pytest.approx(CROWN_RADIUS)


@pytest.mark.parametrize("extinction", [0.05, 0.175, 1.0])
def test_depths_follow_the_truncated_exponential_of_the_crowns_extinction(extinction):
    """Rays through the middle of a 10 m crown, each hit at its near face: their echo depths are Exp(k) cut at the
    chord (Kolmogorov-Smirnov against scipy.stats.truncexpon)."""
    crowns = Crowns(CROWN_CENTRE[None], np.array([[CROWN_RADIUS, CROWN_RADIUS]]), np.array([extinction]))
    n = 4000
    origins = np.tile([0.0, 25.0, 6.0], (n, 1))
    directions = np.tile([1.0, 0.0, 0.0], (n, 1))
    ranges = crown_echo_ranges(crowns, origins, directions, np.full(n, 25.0), np.random.default_rng(7))
    depth = ranges - 25.0
    chord = 2 * CROWN_RADIUS
    assert depth.min() >= 0.0 and depth.max() <= chord
    assert stats.kstest(depth, stats.truncexpon(b=extinction * chord, scale=1.0 / extinction).cdf).pvalue > 0.01


def test_a_hit_no_crown_holds_keeps_its_range():
    ranges = crown_echo_ranges(one_crown(), np.zeros((1, 3)), np.array([[1.0, 0.0, 0.0]]), np.array([12.0]), np.random.default_rng(0))
    assert ranges.tolist() == [12.0]


def crown_and_wall_world() -> World:
    """Water, one crown (a sphere of foliage facets around its envelope) and a wall behind it on the left."""
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=CROWN_RADIUS)
    sphere.apply_translation(CROWN_CENTRE)
    wall = box((1200.0, 1.0, 12.0), (500.0, 40.5, 5.0))
    parts = [water(), Part("tree_crowns", "foliage", VEGETATION, sphere), Part("wall", "wall", CONCRETE, wall)]
    return World("crown", parts, straight_route(), ORIGIN, crowns=one_crown())


def scan_world_points(lidar: HDL32E, world: World, traj: Trajectory, t0: float) -> tuple[np.ndarray, np.ndarray]:
    scan = lidar.scan(world, traj, t0)
    poses = traj.lidar_poses(scan.stamp + scan.points["time"].astype(np.float64))
    xyz = np.einsum("nab,nb->na", poses[:, :3, :3], scan.xyz) + poses[:, :3, 3]
    return xyz, scan.points["label"]


def test_crown_echoes_come_from_inside_the_crown_and_a_walls_from_its_face():
    world = crown_and_wall_world()
    traj = Trajectory(world)
    leaves, facets = HDL32E(**QUIET, foliage_echo="leaves"), HDL32E(**QUIET, foliage_echo="facets")
    for lidar, deep_share in ((facets, 0.0), (leaves, 0.5)):
        xyz, label = scan_world_points(lidar, world, traj, 2.0)
        crown = np.linalg.norm(xyz[label == 1] - CROWN_CENTRE, axis=1)
        assert len(crown) > 300
        assert crown.max() <= CROWN_RADIUS + 0.01
        inside = np.mean(crown < CROWN_RADIUS - 0.5)  # the icosphere's faces lie within 0.02 m of the sphere
        assert inside > deep_share if deep_share else inside == 0.0
        np.testing.assert_allclose(xyz[label == 2, 1], 40.0, atol=1e-3)


def test_crown_echoes_differ_between_revolutions_and_repeat_for_the_same_one():
    """Two revolutions 0.1 s apart: the facets put the crown's echoes on one surface, so each echo of the second has
    one of the first within a few centimetres; the leaves scatter them through the crown (the same distribution of
    depths, but no partner nearby). One revolution cast twice is the same bytes."""
    from scipy.spatial import cKDTree

    world = crown_and_wall_world()
    traj = Trajectory(world)
    gap = {}
    for mode in ("facets", "leaves"):
        lidar = HDL32E(**QUIET, foliage_echo=mode)
        assert lidar.scan(world, traj, 2.0).points.tobytes() == lidar.scan(world, traj, 2.0).points.tobytes()
        (xa, la), (xb, lb) = (scan_world_points(lidar, world, traj, t0) for t0 in (2.0, 2.1))
        a, b = xa[la == 1], xb[lb == 1]
        gap[mode] = np.median(cKDTree(a).query(b)[0])
        if mode == "leaves":
            depth = [CROWN_RADIUS - np.linalg.norm(p - CROWN_CENTRE, axis=1) for p in (a, b)]
            assert stats.ks_2samp(*depth).pvalue > 0.001
    assert gap["facets"] < 0.1 and gap["leaves"] > 3 * gap["facets"]
