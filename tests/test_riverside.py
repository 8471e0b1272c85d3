"""The living riverside: porous crowns (LiDAR and GNSS), docks and moored boats, route clearance, switches, seeds."""

from __future__ import annotations

import gnss_worlds as gw
import numpy as np
import open3d as o3d
import pytest
import trimesh

import worlds
from sim import HDL32E, Trajectory
from sim.gnss import GnssReceiver
from worlds import cache
from worlds.crowns import Crowns
from worlds.materials import CONCRETE, VEGETATION
from worlds.vegetation import Foliage, _facets
from worlds.world import Part, World

RIVERSIDE_KINDS = ("tree", "foliage", "dock", "pontoon", "pile", "moored_boat")


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("RIVERBENCH_CACHE", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def canal():
    return worlds.load("canal_lock", use_cache=False)


def kinds_of(world):
    return {p.kind for p in world.parts}


def test_path_length_through_spheroids_is_the_exact_chord():
    crowns = Crowns(np.array([[20.0, 0.0, 5.0], [0.0, 0.0, 10.0]]), np.array([[3.0, 3.0], [4.0, 2.0]]), np.full(2, 0.175))
    d = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    np.testing.assert_allclose(crowns.path_length([0.0, 0.0, 5.0], d), [6.0, 4.0, 0.0], atol=1e-12)
    # from inside the flat crown straight up: from z = 9 to its top at z = 12
    np.testing.assert_allclose(crowns.path_length([0.0, 0.0, 9.0], d[1:2]), [3.0], atol=1e-12)
    # a chord off the centre of a sphere: 2 sqrt(r^2 - h^2)
    np.testing.assert_allclose(crowns.path_length([0.0, 2.0, 5.0], d[:1]), [2.0 * np.sqrt(9.0 - 4.0)], atol=1e-12)
    assert Crowns.empty().path_length([0, 0, 0], d).tolist() == [0.0, 0.0, 0.0]


def test_rays_through_crowns_pass_as_often_as_the_leaf_density_says_and_hit_inside():
    """Rays through the middle of 40 crowns of radius 5 m: transmittance exp(-density L / 2) with L
    between the inner (facet centres) and outer diameter; hits inside the envelope; normals scattered."""
    rng = np.random.default_rng(1)
    centres = np.c_[np.arange(40) * 30.0, np.zeros(40), np.full(40, 10.0)]
    crowns = Crowns(centres, np.full((40, 2), 5.0), np.full(40, 0.175))
    foliage = Foliage()
    mesh = _facets(crowns, foliage, rng)
    inside = ((mesh.vertices[:, None, :] - centres[None]) ** 2).sum(-1).min(axis=1)
    assert inside.max() <= 25.0 + 1e-9  # every facet vertex inside its crown
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(mesh.vertices.astype(np.float32)), o3d.core.Tensor(mesh.faces.astype(np.uint32)))
    per = 100
    origin = np.repeat(centres, per, axis=0) + rng.uniform(-0.3, 0.3, (40 * per, 3)) - [0.0, 20.0, 0.0]
    rays = np.c_[origin, np.tile([0.0, 1.0, 0.0], (len(origin), 1))].astype(np.float32)
    hit = scene.cast_rays(o3d.core.Tensor(rays))
    t = hit["t_hit"].numpy()
    through = np.isinf(t).mean()
    side = foliage.facet_m
    lo, hi = np.exp(-foliage.leaf_density * 5.0), np.exp(-foliage.leaf_density * (5.0 - side / np.sqrt(3.0)))
    assert lo - 0.04 < through < hi + 0.04, (lo, through, hi)
    y = (origin[:, 1] + t)[np.isfinite(t)]
    assert np.all(np.abs(y) <= 5.0 + 1e-3)
    cos = np.abs(hit["primitive_normals"].numpy()[np.isfinite(t), 1])
    assert 0.35 < cos.mean() < 0.65 and cos.std() > 0.2  # random orientation: mean |cos| 1/2


def _sky_world(extra_parts=(), crowns=None) -> World:
    return World("sky", [gw.water_part(), *extra_parts], gw.route(), gw.ORIGIN, crowns=crowns or Crowns.empty())


def test_satellite_behind_a_crown_loses_the_documented_db_and_one_behind_a_building_is_blocked():
    still = gw.Static(x=300.0)
    open_fix = GnssReceiver(seed=0, filter_mode="raw", noise=gw.NOISE_OFF).fix(_sky_world(), still, 0.0)
    sats = sorted((s for s in open_fix.sats if s.used and 25.0 < s.el_deg < 70.0), key=lambda s: s.el_deg)
    leafy, walled = sats[0], sats[-1]
    antenna = open_fix.truth.enu
    to_leafy = gw.direction(leafy.az_deg, leafy.el_deg)
    radius = 3.0
    crowns = Crowns((antenna + 25.0 * to_leafy)[None], np.array([[radius, radius]]), np.array([0.175]))
    ball = trimesh.creation.icosphere(subdivisions=2, radius=radius)  # a solid ball of leaves: must not block
    ball.apply_translation(crowns.centre[0])
    block = trimesh.creation.box(extents=(4.0, 4.0, 4.0))
    block.apply_translation(antenna + 30.0 * gw.direction(walled.az_deg, walled.el_deg))
    parts = [Part("crown", "foliage", VEGETATION, ball), Part("block", "building", CONCRETE, block)]
    rx = GnssReceiver(seed=0, filter_mode="raw", noise=gw.NOISE_OFF)
    fix = rx.fix(_sky_world(parts, crowns), still, 0.0)
    by_prn = {(s.system, s.prn): (s, t) for s, t in zip(fix.sats, fix.truth.sats)}  # numbers repeat across systems
    report, truth = by_prn[(leafy.system, leafy.prn)]
    assert truth.los and report.used
    loss = rx.config.foliage_loss_db_per_m * 2 * radius  # through the centre: a chord of one diameter
    assert report.snr == pytest.approx(leafy.snr - loss, abs=1e-9)
    assert not by_prn[(walled.system, walled.prn)][1].los
    for s in fix.sats:
        if (s.system, s.prn) not in ((leafy.system, leafy.prn), (walled.system, walled.prn)) and s.snr:
            assert s.snr == pytest.approx(next(o.snr for o in open_fix.sats if (o.system, o.prn) == (s.system, s.prn)), abs=1e-9)
    dense = GnssReceiver(seed=0, filter_mode="raw", noise=gw.NOISE_OFF, foliage_loss_db_per_m=10.0)
    report = next(s for s in dense.fix(_sky_world(parts, crowns), still, 0.0).sats if (s.system, s.prn) == (leafy.system, leafy.prn))
    assert report.snr == 0.0 and not report.used  # 60 dB of foliage: below the tracking threshold


def test_scan_labels_name_the_pontoon_and_the_boats_and_their_geometry(canal):
    dock = next(d for d in canal.params["riverside"]["docks"] if d["name"] == "town_pontoon")
    traj = Trajectory(canal, start_m=dock["station_m"] - 10.0)
    scan = HDL32E(seed=0).scan(canal, traj, 0.0)
    kinds = np.array([p.kind for p in canal.parts])[scan.points["label"]]
    assert {"pontoon", "pile", "moored_boat", "tree", "foliage"} <= set(kinds)
    poses = traj.lidar_poses(scan.stamp + scan.points["time"].astype(np.float64))
    z = (np.einsum("nab,nb->na", poses[:, :3, :3], scan.xyz) + poses[:, :3, 3])[:, 2]
    assert np.all((z[kinds == "pontoon"] > -0.45) & (z[kinds == "pontoon"] < 0.55))  # floating deck: -0.4..0.5 m


@pytest.mark.parametrize("name", ["canal_lock", "charles_river"])
def test_nothing_new_within_the_route_clearance(name, canal):
    world = canal if name == "canal_lock" else worlds.load("charles_river")
    clearance = world.params["route_clearance_m"]
    route = world.route.at(np.arange(0.0, world.route.length, 0.1))[0]
    from scipy.spatial import cKDTree

    tree = cKDTree(route)
    new = world.parts_of_kind(*RIVERSIDE_KINDS)
    assert {p.kind for p in new} == set(RIVERSIDE_KINDS) - ({"dock"} if name == "canal_lock" else set())  # no fixed pier there
    for part in new:
        assert tree.query(part.mesh.vertices[:, :2])[0].min() >= clearance - 0.01, part.name
    assert len(world.crowns) == world.params["riverside"]["trees"] > 50


def test_each_switch_turns_its_parts_off_and_densities_scale(canal):
    assert len(canal.crowns) > 50
    bare = worlds.load("canal_lock", vegetation=False, use_cache=False)
    assert not kinds_of(bare) & {"tree", "foliage"} and len(bare.crowns) == 0
    assert bare.gnss_scene is bare.raycasting_scene
    assert not kinds_of(worlds.load("canal_lock", docks=False, use_cache=False)) & {"dock", "pontoon", "pile"}
    assert "moored_boat" not in kinds_of(worlds.load("canal_lock", moored_boats=False, use_cache=False))
    dense = worlds.load("canal_lock", tree_density=2.0, mooring_density=2.0, use_cache=False)
    assert 1.6 < len(dense.crowns) / len(canal.crowns) < 2.4
    boats = lambda w: sum(len(p.mesh.faces) for p in w.parts_of_kind("moored_boat"))
    assert boats(dense) > boats(canal)
    keys = {
        cache.key("canal_lock", worlds.resolve_params("canal_lock", **kw))
        for kw in ({}, {"vegetation": False}, {"docks": False}, {"moored_boats": False}, {"tree_density": 2.0})
    }
    assert len(keys) == 5


def test_same_seed_same_riverside_other_seed_other_trees(canal):
    again = worlds.load("canal_lock", use_cache=False)
    for kind in RIVERSIDE_KINDS:
        a, b = canal.parts_of_kind(kind), again.parts_of_kind(kind)
        assert [p.name for p in a] == [p.name for p in b]
        assert all(np.array_equal(p.mesh.vertices, q.mesh.vertices) for p, q in zip(a, b))
    other = worlds.load("canal_lock", seed=5, use_cache=False)
    assert not np.array_equal(other.crowns.centre[:5], canal.crowns.centre[:5])


def test_crowns_survive_the_cache(canal, tmp_path):
    path = tmp_path / "w.npz"
    cache.save(canal, path)
    back = cache.read(path)
    np.testing.assert_array_equal(back.crowns.centre, canal.crowns.centre)
    np.testing.assert_array_equal(back.crowns.radius, canal.crowns.radius)
    assert [p.material.name for p in back.parts] == [p.material.name for p in canal.parts]
