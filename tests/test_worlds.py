"""worlds: presets, geometry checked by ray casting, bad inputs, mesh file I/O, cache."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

import worlds
from worlds import cache
from worlds.geometry import untangle

BRIDGE_KINDS = {"bridge_deck", "arch", "girder"}


@pytest.fixture(autouse=True)
def _private_cache(tmp_path, monkeypatch):
    """Every test gets its own cache directory, so none reads or writes the user's."""
    monkeypatch.setenv("RIVERBENCH_CACHE", str(tmp_path / "cache"))


@pytest.fixture(scope="module")
def built():
    """Each preset with default parameters, built fresh once for the module."""
    return {name: worlds.load(name, use_cache=False) for name in worlds.available()}


def cast(world, origins, dirs):
    """(distance, part kind) of the first hit of each ray; inf and '' for misses."""
    import open3d as o3d

    rays = np.c_[np.asarray(origins, np.float32), np.broadcast_to(np.asarray(dirs, np.float32), np.shape(origins))]
    ans = world.raycasting_scene.cast_rays(o3d.core.Tensor(rays.astype(np.float32)))
    t = ans["t_hit"].numpy().astype(float)
    prim = ans["primitive_ids"].numpy()
    kinds = np.array([p.kind for p in world.parts] + [""])
    part = np.where(np.isfinite(t), world.face_part[np.minimum(prim, len(world.face_part) - 1)], len(world.parts))
    return t, kinds[part]


def route_points(world, z, step=1):
    r = world.route
    return np.c_[r.xy[::step], np.full(len(r.xy[::step]), z)]


def structure_stations(world, margin):
    """True per route vertex within `margin` of a structure's shadow or lock chamber."""
    s = world.route.s
    near = np.zeros(len(s), bool)
    for st_ in world.params["structures"]:
        a = min(st_.get("start_m", st_["shadow_start_m"]), st_["shadow_start_m"])
        b = max(st_.get("end_m", st_["shadow_end_m"]), st_["shadow_end_m"])
        near |= (s >= a - margin) & (s <= b + margin)
    return near


def test_available_sorted():
    assert worlds.available() == ["canal_lock", "charles_river", "open_river"]


def test_same_params_identical_mesh_and_seed_changes_buildings(built):
    again = worlds.load("canal_lock", use_cache=False)
    ref = built["canal_lock"]
    assert [p.name for p in again.parts] == [p.name for p in ref.parts]
    for a, b in zip(again.parts, ref.parts):
        assert np.array_equal(a.mesh.vertices, b.mesh.vertices) and np.array_equal(a.mesh.faces, b.mesh.faces)
    other = worlds.load("canal_lock", seed=3, use_cache=False)
    buildings = lambda w: np.concatenate([p.mesh.vertices for p in w.parts_of_kind("building")])
    assert buildings(other).shape != buildings(ref).shape or not np.allclose(buildings(other), buildings(ref))
    assert np.array_equal(other.part("water").mesh.vertices, ref.part("water").mesh.vertices)


@pytest.mark.parametrize("name", ["canal_lock", "charles_river", "open_river"])
def test_route_floats_on_water(built, name):
    """Straight down from 0.5 m above every route vertex, the first thing hit is water at z = 0."""
    world = built[name]
    t, kind = cast(world, route_points(world, 0.5), (0, 0, -1))
    assert (kind == "water").all(), np.unique(kind)
    np.testing.assert_allclose(t, 0.5, atol=1e-4)


@pytest.mark.parametrize("name", ["canal_lock", "charles_river", "open_river"])
def test_route_clear_of_structures(built, name):
    """No geometry within 3 m horizontally of the route from the water up to 3 m (below every deck)."""
    world = built[name]
    angles = np.radians(np.arange(0, 360, 15))
    dirs = np.c_[np.cos(angles), np.sin(angles), np.zeros_like(angles)]
    for z in (0.2, 1.5, 2.9):
        pts = route_points(world, z, step=2)
        origins = np.repeat(pts, len(dirs), axis=0)
        t, kind = cast(world, origins, np.tile(dirs, (len(pts), 1)))
        close = t < 3.0
        assert not close.any(), f"{name}: {close.sum()} rays hit {np.unique(kind[close])} within 3 m at z={z}"


def test_charles_route_keeps_clear_of_piers(built):
    """Every pier and lock wall is at least 6 m from the route horizontally (closest-point query)."""
    import open3d as o3d

    world = built["charles_river"]
    solid = trimesh.util.concatenate([p.mesh for p in world.parts_of_kind("pier", "lock_wall", "lock_gate")])
    flat = trimesh.Trimesh(np.c_[solid.vertices[:, :2], np.zeros(len(solid.vertices))], solid.faces, process=False)
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(flat.vertices.astype(np.float32)), o3d.core.Tensor(flat.faces.astype(np.uint32)))
    dist = scene.compute_distance(o3d.core.Tensor(route_points(world, 0.0).astype(np.float32))).numpy()
    inside_lock = np.zeros(len(dist), bool)
    for st_ in world.params["structures"]:
        if st_["type"] == "lock":
            inside_lock |= (world.route.s >= st_["start_m"] - 1) & (world.route.s <= st_["end_m"] + 1)
    assert dist[~inside_lock].min() > 6.0
    assert dist[inside_lock].min() > 14.0 / 2 - 0.5


@pytest.mark.parametrize("name", ["canal_lock", "charles_river"])
def test_bridge_clearance_above_route(built, name):
    """Straight up from the route at each bridge's station, the first hit is the bridge at its deck height."""
    world = built[name]
    assert world.params["structures"]
    for st_ in world.params["structures"]:
        xy, _ = world.route.at(st_["station_m"])
        t, kind = cast(world, [[*xy, 0.5]], (0, 0, 1))
        expected_kind = BRIDGE_KINDS if st_["type"] != "lock" else {"lock_gate", "bridge_deck"}
        if st_["type"] == "lock":
            xy, _ = world.route.at(0.5 * (st_["shadow_start_m"] + st_["shadow_end_m"]))
            t, kind = cast(world, [[*xy, 0.5]], (0, 0, 1))
        assert kind[0] in expected_kind, (st_["name"], kind[0])
        assert t[0] + 0.5 == pytest.approx(st_["deck_height_m"], abs=2e-3), st_["name"]


def test_bridge_shadow_covers_deck_width(built):
    world = built["charles_river"]
    for st_ in world.params["structures"]:
        if st_["type"].endswith("_bridge"):
            length = st_["shadow_end_m"] - st_["shadow_start_m"]
            assert st_["deck_width_m"] - 2.5 <= length <= st_["deck_width_m"] / np.cos(np.radians(st_["crossing_angle_deg"])) + 2.5


def test_canal_walls_vertical_at_bank_distance():
    """Horizontal rays to both sides hit a vertical wall at the route's left_m / right_m (no moored boats in the way)."""
    world = worlds.load("canal_lock", docks=False, moored_boats=False, use_cache=False)
    r = world.route
    keep = ~structure_stations(world, 15.0)
    pts = route_points(world, 1.0)[keep]
    normal = r.normal_left(r.s[keep])
    for sign, width in ((1, r.left_m[keep]), (-1, r.right_m[keep])):
        t, kind = cast(world, pts, np.c_[sign * normal, np.zeros(len(pts))])
        assert (kind == "wall").all()
        np.testing.assert_allclose(t, width, atol=0.05)


def test_lock_chamber_walls_at_half_width(built):
    world = built["canal_lock"]
    lock = next(s for s in world.params["structures"] if s["type"] == "lock")
    s = np.arange(lock["start_m"] + 1, lock["end_m"] - 1, 1.0)
    xy, _ = world.route.at(s)
    nl = world.route.normal_left(s)
    hits = [cast(world, np.c_[xy, np.ones(len(s))], np.c_[sign * nl, np.zeros(len(s))]) for sign in (1, -1)]
    for t, kind in hits:
        assert set(kind) <= {"lock_wall", "lock_gate"}
        assert_chamber_faces(t, kind, lock["chamber_width_m"])
        assert (kind == "lock_gate").sum() >= 2 * 6  # both open mitre leaves on this side, folded flat in their recesses


def assert_chamber_faces(t, kind, chamber):
    """Sideways hits in a lock chamber: the wall face at half the chamber width, an open mitre leaf
    folded into its recess 0.15 m behind it, or the recess back wall (gate thickness 0.6 + 0.3 m) behind that."""
    half = chamber / 2
    wall_face = (kind == "lock_wall") & np.isclose(t, half, atol=0.05)
    leaf = (kind == "lock_gate") & np.isclose(t, half + 0.15, atol=0.05)
    recess = (kind == "lock_wall") & np.isclose(t, half + 0.9, atol=0.05)
    assert (wall_face | leaf | recess).all(), t[~(wall_face | leaf | recess)]
    assert wall_face.mean() > 0.3


def test_lift_gates_raised_above_route():
    world = worlds.load("canal_lock", lock_gate_type="lift", use_cache=False)
    lock = next(s for s in world.params["structures"] if s["type"] == "lock")
    gates = world.parts_of_kind("lock_gate")[0].mesh
    assert gates.bounds[0, 2] == pytest.approx(9.0, abs=1e-6)
    xy, _ = world.route.at(lock["start_m"] + 4.0)
    t, kind = cast(world, [[*xy, 0.5]], (0, 0, 1))
    assert kind[0] == "lock_gate" and t[0] == pytest.approx(8.5, abs=1e-3)


def test_every_bridge_type_and_kind_present(built):
    types = {s["type"] for w in built.values() for s in w.params["structures"]}
    assert {"beam_bridge", "arch_bridge", "truss_bridge", "lock"} <= types
    charles = built["charles_river"]
    assert {"beam_bridge", "arch_bridge", "truss_bridge", "lock"} <= {s["type"] for s in charles.params["structures"]}
    kinds = {p.kind for p in charles.parts}
    assert {"water", "wall", "quay", "bank", "bridge_deck", "pier", "girder", "arch", "lock_wall", "lock_gate", "building"} <= kinds
    assert all(p.material.name == "steel" for p in charles.parts_of_kind("girder"))
    assert {p.material.name for p in charles.parts_of_kind("building")} == {"brick", "glass", "concrete"}
    assert not built["open_river"].params["structures"]
    assert not built["open_river"].parts_of_kind("building", "pier", "wall")


def test_facades_and_walls_are_truly_vertical(built):
    """Building and wall faces are exactly vertical or exactly horizontal (no slivers leaning)."""
    world = built["charles_river"]
    for part in world.parts_of_kind("building", "wall", "lock_wall"):
        nz = np.abs(part.mesh.face_normals[:, 2])
        assert ((nz < 1e-6) | (nz > 1 - 1e-6)).all(), part.name
        assert (nz < 1e-6).sum() > len(nz) / 3, part.name


def test_charles_layout_follows_real_geography(built):
    world = built["charles_river"]
    assert 4500 <= world.route.length <= 5100
    places = {
        "bu_bridge": (0, 0),
        "harvard_bridge": (1570, 200),
        "longfellow_bridge": (2900, 830),
        "museum_dam_bridge": (3260, 1540),
        "charles_river_dam_lock": (3950, 1640),
        "charlestown_bridge": (4100, 1780),
    }
    st_ = {s["name"]: s for s in world.params["structures"]}
    assert [s["name"] for s in world.params["structures"]] == list(places)
    for name, enu in places.items():
        xy, _ = world.route.at(st_[name]["station_m"])
        assert np.linalg.norm(xy - enu) < 3.0, name
    assert st_["harvard_bridge"]["piers"] >= 18
    assert 550 <= st_["harvard_bridge"]["length_m"] <= 700
    basin = (world.route.s > st_["bu_bridge"]["station_m"] + 400) & (world.route.s < st_["longfellow_bridge"]["station_m"])
    assert world.route.right_m[basin].min() >= 40 and world.route.right_m[basin].max() <= 80
    width = world.route.left_m + world.route.right_m
    assert width[basin].max() > 450
    tall = max(p.mesh.bounds[1, 2] for p in world.parts_of_kind("building"))
    assert 60 <= tall <= 105


def test_canal_straight_stretch_is_straight_and_empty(built):
    world = built["canal_lock"]
    a, b = world.params["straight_stretch_m"]
    assert b - a >= 150
    i = (world.route.s >= a) & (world.route.s <= b)
    assert np.ptp(world.route.heading[i]) < np.radians(0.5)
    for st_ in world.params["structures"]:
        assert st_["shadow_start_m"] > b + 50 or st_["shadow_end_m"] < a - 50
    xy, _ = world.route.at(np.array([a, b]))
    for p in world.parts_of_kind("building"):
        v = p.mesh.vertices[:, :2]
        along = (v - xy[0]) @ ((xy[1] - xy[0]) / np.linalg.norm(xy[1] - xy[0]))
        assert not ((along > 0) & (along < b - a)).any()


@pytest.mark.parametrize(
    "overrides, key",
    [
        ({"width_m": -5}, "width_m"),
        ({"wall_height": 3}, "wall_height"),
        ({"lock_chamber_width_m": 30}, "chamber_width_m"),
        ({"bridges": [{"name": "b", "type": "beam", "station_m": 5000.0}]}, "station_m"),
        ({"bridges": [{"name": "b", "type": "beam", "station_m": 100.0, "deck_width_m": 0}]}, "deck_width_m"),
        ({"bridges": [{"name": "b", "type": "suspension", "station_m": 100.0}]}, "type"),
        ({"bridges": [{"name": "b", "type": "beam", "station_m": 100.0, "length_m": 5}]}, "length_m"),
        ({"bridges": [{"name": "b", "type": "arch", "station_m": 100.0, "pier_spacing_m": 10, "pier_width_m": 9}]}, "pier_width_m"),
        (
            {"bridges": [{"name": "b", "type": "beam", "station_m": 100.0, "pier_spacing_m": 8, "pier_width_m": 5, "crossing_angle_deg": 30}]},
            "pier_spacing_m",
        ),
        ({"seed": -1}, "seed"),
    ],
)
def test_bad_parameters_name_the_key(overrides, key):
    with pytest.raises(ValueError, match=key) as info:
        worlds.load("canal_lock", use_cache=False, **overrides)
    assert "\n" not in str(info.value)


def test_unknown_preset_lists_available():
    with pytest.raises(ValueError, match="canal_lock, charles_river, open_river"):
        worlds.load("amazon")


@pytest.mark.parametrize(
    "content, problem",
    [
        ("this is not a mesh\n", "could not be read|no triangles"),
        ("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "NaN"),
        ("v 0 0 0\nv 1 0 0\n", "no triangles"),
    ],
)
def test_bad_mesh_files(tmp_path, content, problem):
    path = tmp_path / "bad.obj"
    path.write_text(content)
    with pytest.raises(ValueError, match=problem) as info:
        worlds.load(path)
    assert "\n" not in str(info.value)


def test_missing_and_garbage_binary_files(tmp_path):
    with pytest.raises(ValueError, match="does not exist"):
        worlds.load(tmp_path / "nothing.ply")
    garbage = tmp_path / "garbage.ply"
    garbage.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 99\n\x00\x01")
    with pytest.raises(ValueError, match="garbage.ply"):
        worlds.load(garbage)


@pytest.mark.parametrize("ext", ["ply", "glb", "obj", "stl"])
def test_export_then_load_round_trip(built, tmp_path, ext):
    world = built["canal_lock"]
    path = worlds.export(world, tmp_path / f"canal.{ext}")
    assert [p.name for p in tmp_path.iterdir()] == [f"canal.{ext}"]  # no temp file left
    again = worlds.load(path)
    assert len(again.mesh.faces) == len(world.mesh.faces)
    np.testing.assert_allclose(again.mesh.bounds, world.mesh.bounds, atol=1e-3)
    assert again.parts[0].kind == "other"


def test_export_unsupported_format_leaves_nothing(built, tmp_path):
    with pytest.raises(ValueError, match="format 'xyzq'"):
        worlds.export(built["open_river"], tmp_path / "w.xyzq")
    assert not list(tmp_path.iterdir())


def test_file_world_default_and_given_route(tmp_path):
    box = trimesh.creation.box(extents=(200.0, 40.0, 6.0))
    box.apply_translation((100.0, 50.0, 0.0))
    path = tmp_path / "box.stl"
    box.export(path)
    world = worlds.load(path)
    np.testing.assert_allclose(world.route.xy[[0, -1]], [[0.0, 50.0], [200.0, 50.0]], atol=1e-6)
    assert world.route.left_m[0] == pytest.approx(20.0)
    world = worlds.load(path, route=[[0, 50], [50, 60], [120, 50]], left_m=10, right_m=12)
    np.testing.assert_allclose(world.route.xy[0], [0, 50])
    assert world.route.right_m[0] == 12
    with pytest.raises(ValueError, match="'colour'"):
        worlds.load(path, colour="red")


def test_add_mesh_part(built, tmp_path):
    base = built["open_river"]
    path = tmp_path / "buoy.ply"
    trimesh.creation.cylinder(radius=0.5, height=2.0).export(path)
    shift = np.eye(4)
    shift[:3, 3] = (100.0, 20.0, 0.5)
    world = worlds.add_mesh_part(base, path, name="buoy", kind="other", material="steel", transform=shift)
    assert len(world.parts) == len(base.parts) + 1
    buoy = world.part("buoy")
    assert buoy.material.name == "steel" and buoy.kind == "other"
    np.testing.assert_allclose(buoy.mesh.bounds.mean(axis=0)[:2], (100.0, 20.0), atol=1e-6)
    assert world.params["extra_parts"][0]["name"] == "buoy"
    with pytest.raises(ValueError, match="kind 'rock'"):
        worlds.add_mesh_part(base, path, kind="rock")


def test_cached_load_equals_fresh_build_and_survives_corruption(built):
    first = worlds.load("open_river")
    entries = list(cache.cache_dir().glob("open_river-*.npz"))
    assert len(entries) == 1
    second = worlds.load("open_river")
    fresh = built["open_river"]
    for world in (first, second):
        assert [(p.name, p.kind, p.material) for p in world.parts] == [(p.name, p.kind, p.material) for p in fresh.parts]
        for a, b in zip(world.parts, fresh.parts):
            assert np.array_equal(a.mesh.vertices, b.mesh.vertices) and np.array_equal(a.mesh.faces, b.mesh.faces)
        for field in ("xy", "s", "heading", "left_m", "right_m"):
            assert np.array_equal(getattr(world.route, field), getattr(fresh.route, field))
        assert world.params == fresh.params and world.origin == fresh.origin
    entries[0].write_bytes(b"not an npz")
    third = worlds.load("open_river")
    assert len(third.mesh.faces) == len(fresh.mesh.faces)
    assert cache.read(entries[0]).params == fresh.params  # rewritten
    worlds.load("open_river", width_m=300)
    assert len(list(cache.cache_dir().glob("open_river-*.npz"))) == 2


def test_describe(built):
    d = worlds.describe(built["charles_river"])
    assert d["triangles"] == len(built["charles_river"].mesh.faces) == sum(k["triangles"] for k in d["kinds"].values())
    assert d["triangles"] < 300_000
    assert d["route_length_m"] == pytest.approx(built["charles_river"].route.length, abs=1e-3)
    assert {s["name"] for s in d["structures"]} >= {"harvard_bridge", "longfellow_bridge"}
    assert d["bounds"]["min"][2] < 0 < d["bounds"]["max"][2]


def test_resolved_params_are_complete_and_json():
    import json

    world = worlds.load("canal_lock", width_m=30, seed=3, use_cache=False)
    params = json.loads(json.dumps(world.params))
    assert params["width_m"] == 30 and params["seed"] == 3 and params["wall_height_m"] == 3.0
    assert {"name", "type", "station_m", "deck_height_m", "deck_width_m"} <= set(params["structures"][0])
    assert {(e["side"], e["type"]) for e in params["edges"]} == {("left", "wall"), ("right", "wall")}
    assert params["edges"][0]["start_m"] == 0 and params["edges"][0]["end_m"] == pytest.approx(world.route.length)
    assert len(params["building_rows"]) == 2


def test_charles_edges_record_sea_walls_and_quays(built):
    edges = built["charles_river"].params["edges"]
    right = [e for e in edges if e["side"] == "right"]
    assert [e["type"] for e in right] == ["wall", "quay"]
    assert right[0]["material"] == "granite" and right[0]["end_m"] > 2500


def _self_crossings(pts):
    """Number of proper crossings between non-adjacent, non-degenerate segments of a polyline."""
    a, b = pts[:-1], pts[1:]
    ok = np.linalg.norm(b - a, axis=1) > 1e-9

    def orient(o, p, q):
        return (p[..., 0] - o[..., 0]) * (q[..., 1] - o[..., 1]) - (p[..., 1] - o[..., 1]) * (q[..., 0] - o[..., 0])

    A, B, C, D = a[:, None], b[:, None], a[None], b[None]
    cross = (orient(A, B, C) * orient(A, B, D) < -1e-9) & (orient(C, D, A) * orient(C, D, B) < -1e-9)
    n = len(a)
    cross &= np.triu(np.ones((n, n), bool), 2) & ok[:, None] & ok[None]
    return int(cross.sum())


@settings(max_examples=25, deadline=None)
@given(radius=st.floats(5.0, 60.0), offset=st.floats(1.0, 150.0), turn=st.floats(20.0, 150.0))
def test_untangle_leaves_no_loops(radius, offset, turn):
    """Offsetting a bend (straight in and out, like the extended route) by more than its radius on
    the inner side gives a curve without loops, and no point is left inside the offset distance."""
    ang = np.radians(np.linspace(-90, -90 + turn, 60))
    exit_dir = np.array([-np.sin(ang[-1]), np.cos(ang[-1])])
    line = np.r_[
        np.c_[np.linspace(-1000, 0, 60)[:-1], np.full(59, -radius)],
        np.c_[radius * np.cos(ang), radius * np.sin(ang)],
        radius * np.array([np.cos(ang[-1]), np.sin(ang[-1])]) + np.linspace(0, 1000, 60)[1:, None] * exit_dir,
    ]
    d = np.gradient(line, axis=0)
    nl = np.c_[-d[:, 1], d[:, 0]] / np.linalg.norm(d, axis=1)[:, None]
    pts = untangle(line + offset * nl)
    assert _self_crossings(pts) == 0
    dense = np.concatenate([np.linspace(line[k], line[k + 1], 10) for k in range(len(line) - 1)])
    dist = np.linalg.norm(pts[:, None] - dense[None], axis=2).min(axis=1)
    assert dist.min() > offset - max(0.05 * offset, 0.6)


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    width=st.floats(16.0, 50.0),
    wall=st.floats(1.0, 6.0),
    deck=st.floats(3.2, 8.0),
    gate=st.sampled_from(["mitre", "lift"]),
    chamber_frac=st.floats(0.3, 0.9),
)
def test_canal_invariants_over_parameters(width, wall, deck, gate, chamber_frac):
    chamber = max(5.0, chamber_frac * (width - 2.5))
    world = worlds.load(
        "canal_lock",
        width_m=width,
        wall_height_m=wall,
        bridge_deck_height_m=deck,
        lock_gate_type=gate,
        lock_chamber_width_m=chamber,
        buildings=False,
        docks=False,
        moored_boats=False,
        use_cache=False,
    )
    t, kind = cast(world, route_points(world, 0.5, step=5), (0, 0, -1))
    assert (kind == "water").all()
    keep = ~structure_stations(world, 15.0)
    r = world.route
    t, kind = cast(world, route_points(world, 0.5)[keep], np.c_[r.normal_left(r.s[keep]), np.zeros(keep.sum())])
    assert (kind == "wall").all()
    np.testing.assert_allclose(t, width / 2, atol=0.05)
    walls = np.concatenate([p.mesh.vertices for p in world.parts_of_kind("wall")])
    assert walls[:, 2].max() == pytest.approx(wall)
    lock = next(s for s in world.params["structures"] if s["type"] == "lock")
    inside = (r.s > lock["start_m"] + 1) & (r.s < lock["end_m"] - 1)
    for sign in (1, -1):
        t, kind = cast(world, route_points(world, 1.0)[inside], np.c_[sign * r.normal_left(r.s[inside]), np.zeros(inside.sum())])
        assert set(kind) <= {"lock_wall", "lock_gate"}
        assert_chamber_faces(t, kind, chamber)
    for st_ in world.params["structures"]:
        if st_["type"] != "lock":
            xy, _ = r.at(st_["station_m"])
            t, kind = cast(world, [[*xy, 0.2]], (0, 0, 1))
            assert kind[0] in BRIDGE_KINDS and t[0] + 0.2 == pytest.approx(deck, abs=2e-3)


@pytest.mark.parametrize("kind, spacing_key, depth_key", [("beam", "girder_spacing_m", "girder_depth_m"), ("arch", "rib_spacing_m", "rib_depth_m")])
def test_girders_and_ribs_face_along_the_route(kind, spacing_key, depth_key):
    """Under a girder or rib bridge crossing square, a ray along the route at mid-depth from midway
    between two members meets the next one's side at half the spacing less half its width (the
    surfaces that let a scan matcher measure motion along the route under a deck)."""
    spacing, depth, clearance = 4.0, 1.5, 6.0
    spec = dict(
        name="b",
        type=kind,
        station_m=800.0,
        deck_height_m=clearance,
        deck_width_m=24.0,
        pier_spacing_m=40.0,
        **{spacing_key: spacing, depth_key: depth},
    )
    world = worlds.load("open_river", bridges=[spec], use_cache=False)
    xy, heading = world.route.at(800.0)
    ahead = np.array([np.cos(heading), np.sin(heading)])
    start = np.r_[xy + ahead * spacing / 2, clearance + depth / 2]
    t, kind_hit = cast(world, [start, start], [np.r_[ahead, 0.0], np.r_[-ahead, 0.0]])
    half_width = 0.015 if kind == "beam" else 0.4  # a girder's web, a rib
    assert set(kind_hit) == {"girder" if kind == "beam" else "arch"}
    assert t == pytest.approx(spacing / 2 - half_width, abs=0.02)


@settings(max_examples=8, deadline=None)
@given(
    kind=st.sampled_from(["beam", "arch", "truss"]),
    station=st.floats(300.0, 1700.0),
    angle=st.floats(-40.0, 40.0),
    deck=st.floats(3.0, 15.0),
    width=st.floats(4.0, 40.0),
    spacing=st.floats(12.0, 120.0),
    pier=st.floats(0.5, 4.0),
    members=st.sampled_from([0.0, 2.5, 6.0]),
)
def test_any_bridge_spans_the_route_at_its_clearance(kind, station, angle, deck, width, spacing, pier, members):
    """The deck (on a slab, a vault, girders or ribs) is at its clearance over the route; piers keep the clearance that spacing, pier width
    and the crossing angle leave (mid-span at the station, slanting across a wide deck)."""
    # gap along the bridge axis at the pier's end (deck width + 1 m each side), times cos(angle) for
    # the perpendicular distance from a route crossing at that angle; less the route's bend over the
    # pier's length (sagitta L^2 kappa / 8, at least 15 cm), which the straight-crossing formula leaves
    # out (open_river at 300 m bends at R = 1128 m: 18 cm over a 34 m deck crossed at 28 deg)
    gap_u = spacing / 2 - pier / 2 - abs(np.tan(np.radians(angle))) * (width / 2 + 1.0)
    along = np.arange(station - 30.0, station + 31.0)
    kappa = np.abs(np.diff(np.unwrap(worlds.load("open_river").route.at(along)[1]))).max()  # rad per 1 m step
    bend = max(0.15, ((width + 2.0) / np.cos(np.radians(angle))) ** 2 * kappa / 8.0)
    clearance = gap_u * np.cos(np.radians(angle)) - bend
    assume(clearance > 1.2)
    spec = dict(
        name="b",
        type=kind,
        station_m=station,
        crossing_angle_deg=angle,
        deck_height_m=deck,
        deck_width_m=width,
        pier_spacing_m=spacing,
        pier_width_m=pier,
    )
    spec |= {"beam": {"girder_spacing_m": members}, "arch": {"rib_spacing_m": members}}.get(kind, {})
    world = worlds.load("open_river", bridges=[spec], use_cache=False)
    (placed,) = world.params["structures"]
    xy, _ = world.route.at(station)
    t, kind_hit = cast(world, [[*xy, 0.2]], (0, 0, 1))
    assert kind_hit[0] in BRIDGE_KINDS and t[0] + 0.2 == pytest.approx(deck, abs=2e-3)
    assert placed["shadow_start_m"] < station < placed["shadow_end_m"]
    near = np.abs(world.route.s - station) < width + 10
    angles = np.radians(np.arange(0, 360, 10))
    dirs = np.c_[np.cos(angles), np.sin(angles), np.zeros_like(angles)]
    pts = route_points(world, min(2.0, deck - 0.5))[near]
    t, _ = cast(world, np.repeat(pts, len(dirs), axis=0), np.tile(dirs, (len(pts), 1)))
    assert t.min() > min(clearance, 3.0)


def test_normals_face_out_of_solids_and_up_from_water(built):
    """Straight up from the route the first face hit looks down at it; straight down, water looks up;
    sideways, walls and lock walls face the vessel (outward-facing solids, as the GNSS probes assume)."""
    for world in (built["canal_lock"], built["charles_river"]):
        import open3d as o3d

        pts = route_points(world, 0.5)
        for direction in ((0, 0, 1), (0, 0, -1)):
            rays = np.c_[pts, np.broadcast_to(direction, pts.shape)].astype(np.float32)
            ans = world.raycasting_scene.cast_rays(o3d.core.Tensor(rays))
            hit = np.isfinite(ans["t_hit"].numpy())
            facing = np.einsum("ij,ij->i", ans["primitive_normals"].numpy()[hit], rays[hit, 3:])
            assert (facing < 0).all(), (world.name, direction, int((facing >= 0).sum()))
        r = world.route
        for sign in (1, -1):
            dirs = np.c_[sign * r.normal_left(r.s), np.zeros(len(r.s))]
            rays = np.c_[route_points(world, 1.0), dirs].astype(np.float32)
            ans = world.raycasting_scene.cast_rays(o3d.core.Tensor(rays))
            hit = np.isfinite(ans["t_hit"].numpy())
            facing = np.einsum("ij,ij->i", ans["primitive_normals"].numpy()[hit], rays[hit, 3:])
            assert (facing < 0).mean() > 0.99, (world.name, sign)


def test_tight_bend_channel_keeps_walls_out_of_the_channel():
    """A 90 deg bend of radius ~25 m with 60 m to the inner wall: no wall reaches into the channel
    (every edge or ground vertex above the water is at least its side's width from the route)."""
    from worlds.channel import ChannelParams, EdgeStretch, build_channel
    from worlds.route import Route
    from worlds.world import World

    ang = np.radians(np.linspace(-90, 0, 10))
    wp = np.r_[[[-300.0, -25.0], [-150.0, -25.0]], np.c_[25 * np.cos(ang), 25 * np.sin(ang)], [[25.0, 150.0], [25.0, 300.0]]]
    route = Route.from_waypoints(wp, left_m=60.0, right_m=20.0)
    params = ChannelParams(stretches=[EdgeStretch(side="left", start_m=300, end_m=350, type="bank")])
    world = World("bend", build_channel(route, params), route, (0.0, 0.0, 0.0))
    angles = np.radians(np.arange(0, 360, 5))
    dirs = np.c_[np.cos(angles), np.sin(angles), np.zeros_like(angles)]
    for z in (0.5, 1.5):
        pts = route_points(world, z, step=3)
        t, kind = cast(world, np.repeat(pts, len(dirs), axis=0), np.tile(dirs, (len(pts), 1)))
        assert t.min() > 20.0 - 0.3, np.unique(kind[t < 19.7])
    t, kind = cast(world, route_points(world, 0.5), (0, 0, -1))
    assert (kind == "water").all()
    dense = np.concatenate([np.linspace(route.xy[k], route.xy[k + 1], 5) for k in range(len(route.xy) - 1)])
    for side, width in (("left", 60.0), ("right", 20.0)):
        v = np.concatenate([p.mesh.vertices for p in world.parts if p.name.startswith(side)])
        v = v[v[:, 2] > 0.1, :2]
        inside = np.array([np.linalg.norm(dense - q, axis=1).min() for q in v])
        assert inside.min() > width - 0.5, (side, inside.min())
