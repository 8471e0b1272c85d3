"""Open3D RaycastingScene against trimesh's embree intersector (embreex) on the project's own rays:
scene build time, rays per second, the embree/Open3D speed ratio and the agreement of the results.

Query types, the same rays for both contenders:

  lidar first   one HDL-32E revolution (HDL32E.rays, as sim/lidar.py casts it) from a charles_river
                route pose just before a bridge, first hit on the full world mesh (world.raycasting_scene).
  gnss first    one GNSS epoch at a canal_lock route position between buildings: the probe, sky and
                reflection-leg rays exactly as sim.visibility.trace builds them inside GnssReceiver.fix
                (captured from that call), first hit on the foliage-free mesh (world.gnss_scene).
  lidar multi   every intersection along the revolution's rays (full mesh).
  gnss multi    every intersection along the epoch's rays on the full mesh, foliage included (what a
                foliage-penetration or multi-reflection model would need).

Contenders: Open3D `cast_rays` / `list_intersections` (default threads, as the project calls them, and
nthreads=1 for reference) and trimesh.ray.ray_pyembree.RayMeshIntersector: `intersects_first` (triangle
index: the hit/miss verdict), `intersects_location(multiple_hits=False)` (first hit with its location,
hence the distance a LiDAR or a reflection leg needs), `intersects_location(multiple_hits=True)`.
Every round calls each contender in turn (A, B, A, B ...) on the same rays; per round the time is
the mean over `--reps` calls; printed are medians over rounds and the median of the per-round ratios.

Agreement: share of rays with the same hit/miss verdict, share of rays both hit whose first triangle
is the same, max |distance difference| on rays both hit; for multi-hit, share of rays with the same
number of hits (raw, and after merging hits closer than --merge-m along a ray, i.e. duplicates at
shared edges or coincident faces) and max |distance difference| on rays with equal counts; for the
GNSS epoch also the verdicts sim.visibility derives (line of sight, reflection clear, inside solid).

    .venv/bin/python benchmarks/embree.py [--rounds 7] [--reps 3] [--gnss-reps 200] [--bridge harvard_bridge_deck]
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from contextlib import contextmanager

import numpy as np
import open3d as o3d
import trimesh
from trimesh.ray.ray_pyembree import RayMeshIntersector

import sim.gnss
import worlds
from sim import HDL32E, GnssReceiver, Trajectory
from sim.visibility import PROBES, START_OFFSET_M

# ---------------------------------------------------------------------------------------------- scenes


def open3d_scene(mesh: trimesh.Trimesh) -> o3d.t.geometry.RaycastingScene:
    """As worlds.world._scene builds it; the first cast commits Embree's BVH, so it is part of the build."""
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)), o3d.core.Tensor(np.asarray(mesh.faces, dtype=np.uint32)))
    scene.cast_rays(o3d.core.Tensor(np.array([[0, 0, 1e4, 0, 0, 1]], dtype=np.float32)))
    return scene


def embree_scene(mesh: trimesh.Trimesh) -> RayMeshIntersector:
    """trimesh's embreex intersector, committed by one query; the multi-hit path also needs the mesh's
    triangles and face normals (cached on the mesh), counted here too."""
    intersector = RayMeshIntersector(mesh)
    intersector.intersects_first(np.array([[0, 0, 1e4]]), np.array([[0, 0, 1.0]]))
    mesh.triangles, mesh.face_normals  # noqa: B018
    return intersector


def fresh(mesh: trimesh.Trimesh) -> trimesh.Trimesh:
    """An uncached copy, so every build starts cold."""
    return trimesh.Trimesh(np.array(mesh.vertices), np.array(mesh.faces), process=False)


# ------------------------------------------------------------------------------------------------- rays


def time_near(traj: Trajectory, station_m: float) -> float:
    """The time the vessel reaches route station `station_m`."""
    t = np.linspace(0.0, traj.duration, 200_001)
    return float(t[min(np.searchsorted(traj.station(t), station_m), len(t) - 1)])


def lidar_rays(world: worlds.World, bridge: str, before_m: float) -> tuple[np.ndarray, float]:
    """One revolution's (N, 6) float32 rays, `before_m` metres of route before the bridge's middle."""
    centre = world.part(bridge).mesh.bounds.mean(axis=0)
    station = world.route.station_of(centre[:2]) - before_m
    traj = Trajectory(world)
    return HDL32E().rays(traj, time_near(traj, station)), station


def between_buildings(world: worlds.World, step_m: float = 5.0, along_m: float = 30.0, across_m: float = 60.0) -> tuple[float, int, int]:
    """Route station with the most building vertices on its poorer side (within along_m x across_m):
    built up on both banks. Returns (station, vertices left, vertices right)."""
    v = np.concatenate([np.asarray(p.mesh.vertices)[:, :2] for p in world.parts_of_kind("building")])
    best = (0.0, -1, -1)
    for s in np.arange(along_m, world.route.length - along_m, step_m):
        xy, heading = world.route.at(s)
        rel = v - xy
        a = rel @ np.array([np.cos(heading), np.sin(heading)])
        c = rel @ world.route.normal_left(s)
        near = np.abs(a) < along_m
        n_left, n_right = int((near & (c > 0) & (c < across_m)).sum()), int((near & (c < 0) & (c > -across_m)).sum())
        if min(n_left, n_right) > min(best[1], best[2]):
            best = (float(s), n_left, n_right)
    return best


class _Recorder:
    """Stands in for world.gnss_scene inside sim.visibility.trace: records the rays, casts for real."""

    def __init__(self, scene):
        self.scene, self.rays = scene, None

    def cast_rays(self, rays):
        self.rays = rays.numpy().copy()
        return self.scene.cast_rays(rays)


@contextmanager
def _recording(store: list):
    trace = sim.gnss.trace

    def recording(scene, antenna, directions, reflections, movers=None):
        rec = _Recorder(scene)
        out = trace(rec, antenna, directions, reflections, movers)
        store.append((rec.rays, antenna.copy(), len(directions), len(reflections), out))
        return out

    sim.gnss.trace = recording
    try:
        yield
    finally:
        sim.gnss.trace = trace


def gnss_rays(world: worlds.World) -> dict:
    """One epoch's rays as GnssReceiver.fix casts them (via sim.visibility.trace) at the canal position."""
    station, n_left, n_right = between_buildings(world)
    traj = Trajectory(world)
    t = time_near(traj, station)
    store: list = []
    with _recording(store):
        GnssReceiver().fix(world, traj, t)
    rays, antenna, m, k, paths = store[0]
    return dict(rays=rays, antenna=antenna, m=m, k=k, paths=paths, station=station, t=t, left=n_left, right=n_right)


# ---------------------------------------------------------------------------------------------- queries


def o3d_first(scene, rays: np.ndarray, nthreads: int = 0) -> dict:
    hit = scene.cast_rays(o3d.core.Tensor.from_numpy(rays), nthreads=nthreads)
    return {k: hit[k].numpy() for k in ("t_hit", "primitive_ids", "primitive_normals")}


def o3d_multi(scene, rays: np.ndarray, nthreads: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(ray index, distance) of every intersection."""
    lx = scene.list_intersections(o3d.core.Tensor.from_numpy(rays), nthreads=nthreads)
    return lx["ray_ids"].numpy().astype(np.int64), lx["t_hit"].numpy()


def embree_first(intersector: RayMeshIntersector, rays: np.ndarray) -> np.ndarray:
    return intersector.intersects_first(rays[:, :3], rays[:, 3:])


def embree_location(intersector: RayMeshIntersector, rays: np.ndarray, multiple: bool) -> tuple:
    """(ray index, distance, triangle) of the first or of every intersection."""
    loc, ray, tri = intersector.intersects_location(rays[:, :3], rays[:, 3:], multiple_hits=multiple)
    d = np.einsum("ij,ij->i", loc - rays[ray, :3], rays[ray, 3:])
    return ray, d, tri


# -------------------------------------------------------------------------------------------- agreement


def first_agreement(ref: dict, tri: np.ndarray, loc: tuple, n: int) -> dict:
    hit_o3d = np.isfinite(ref["t_hit"])
    hit_emb = tri != -1
    both = hit_o3d & hit_emb
    d = np.full(n, np.inf)
    d[loc[0]] = loc[1]
    loc_hit = np.isfinite(d)
    diff = np.abs(d[both & loc_hit] - ref["t_hit"][both & loc_hit])
    return dict(
        verdict=float((hit_o3d == hit_emb).mean()),
        n_disagree=int((hit_o3d != hit_emb).sum()),
        same_tri=float((ref["primitive_ids"][both] == tri[both]).mean()) if both.any() else 1.0,
        max_dd=float(diff.max()) if len(diff) else 0.0,
        p999_dd=float(np.quantile(diff, 0.999)) if len(diff) else 0.0,
        loc_verdict=float((hit_o3d == loc_hit).mean()),
        hits=int(hit_o3d.sum()),
    )


def _per_ray(ray: np.ndarray, d: np.ndarray, n: int, merge_m: float) -> tuple[np.ndarray, list[np.ndarray]]:
    order = np.lexsort((d, ray))
    ray, d = ray[order], d[order]
    if merge_m > 0 and len(d):
        keep = np.r_[True, (np.diff(ray) != 0) | (np.diff(d) > merge_m)]
        ray, d = ray[keep], d[keep]
    counts = np.bincount(ray, minlength=n)
    return counts, np.split(d, np.cumsum(counts)[:-1])


def multi_agreement(ref: tuple, emb: tuple, n: int, merge_m: float) -> dict:
    out = dict(hits_o3d=len(ref[0]), hits_emb=len(emb[0]))
    for tag, tol in (("raw", 0.0), ("merged", merge_m)):
        c_o3d, d_o3d = _per_ray(ref[0], ref[1], n, tol)
        c_emb, d_emb = _per_ray(emb[0], emb[1], n, tol)
        same = c_o3d == c_emb
        verdict = (c_o3d > 0) == (c_emb > 0)
        dd = np.array([np.abs(d_o3d[i] - d_emb[i]).max() for i in np.flatnonzero(same & (c_o3d > 0))])
        out[tag] = dict(
            same_count=float(same.mean()),
            verdict=float(verdict.mean()),
            max_dd=float(dd.max()) if len(dd) else 0.0,
            p999_dd=float(np.quantile(dd, 0.999)) if len(dd) else 0.0,
            more_o3d=int((c_o3d > c_emb).sum()),
            more_emb=int((c_emb > c_o3d).sum()),
        )
    return out


def gnss_verdicts(g: dict, mesh: trimesh.Trimesh, loc: tuple) -> dict:
    """sim.visibility.trace's verdicts recomputed from embree's first hits, against those trace returned."""
    rays, m, k = g["rays"], g["m"], g["k"]
    p = len(PROBES)
    t_hit = np.full(len(rays), np.inf)
    t_hit[loc[0]] = loc[1]
    normals = np.zeros((len(rays), 3))
    normals[loc[0]] = mesh.face_normals[loc[2]]
    inside = bool(np.isfinite(t_hit[:p]).all() and ((normals[:p] * PROBES).sum(1) > 0).all())
    los = np.isinf(t_hit[p : p + m])
    leg = np.linalg.norm(g["antenna"] - rays[p + m + k :, :3], axis=1)
    clear = np.isinf(t_hit[p + m : p + m + k]) & (t_hit[p + m + k :] >= leg - START_OFFSET_M)
    ref = g["paths"]
    return dict(los=int((los == ref.los).sum()), m=m, clear=int((clear == ref.reflection_clear).sum()), k=k, inside=inside == ref.inside_solid)


# --------------------------------------------------------------------------------------------- timing


def rounds(contenders: dict[str, Callable[[], object]], n_rounds: int, reps: int) -> dict[str, list[float]]:
    """Seconds per call of each contender per round; within a round the contenders take turns."""
    for fn in contenders.values():
        fn()  # warm up
    out: dict[str, list[float]] = {name: [] for name in contenders}
    for _ in range(n_rounds):
        for name, fn in contenders.items():
            start = time.perf_counter()
            for _ in range(reps):
                fn()
            out[name].append((time.perf_counter() - start) / reps)
    return out


def build_rounds(mesh: trimesh.Trimesh, n_rounds: int) -> dict[str, list[float]]:
    out: dict[str, list[float]] = {"open3d": [], "embree": []}
    for _ in range(n_rounds):
        for name, build in (("open3d", open3d_scene), ("embree", embree_scene)):
            m = fresh(mesh)
            start = time.perf_counter()
            build(m)
            out[name].append(time.perf_counter() - start)
    return out


def fmt_rate(n_rays: int, seconds: float) -> str:
    r = n_rays / seconds
    return f"{r / 1e6:7.2f} M" if r >= 1e6 else f"{r / 1e3:7.1f} k"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--reps", type=int, default=3, help="calls per round and contender for the revolution queries")
    parser.add_argument("--gnss-reps", type=int, default=200, help="calls per round and contender for the epoch queries")
    parser.add_argument("--build-rounds", type=int, default=3)
    parser.add_argument("--bridge", default="harvard_bridge_deck", help="charles_river part the LiDAR pose is before")
    parser.add_argument("--before", type=float, default=20.0, help="metres of route before the bridge's middle")
    parser.add_argument("--merge-m", type=float, default=0.01, help="multi-hit: hits closer than this along a ray count once")
    args = parser.parse_args()

    river, canal = worlds.load("charles_river"), worlds.load("canal_lock")
    lidar, station = lidar_rays(river, args.bridge, args.before)
    g = gnss_rays(canal)
    canal_solid = trimesh.util.concatenate([p.mesh for p in canal.parts if not p.material.foliage])
    n_l, n_g = len(lidar), len(g["rays"])
    print(f"open3d {o3d.__version__}, trimesh {trimesh.__version__}; rounds {args.rounds} (A, B, ... per round)")
    print(
        f"(a) charles_river, {len(river.mesh.faces)} triangles: one HDL-32E revolution, {n_l} rays, station "
        f"{station:.0f} m ({args.before:g} m before {args.bridge}'s middle)"
    )
    print(
        f"(b) canal_lock, {len(canal_solid.faces)} solid triangles ({len(canal.mesh.faces)} with foliage): one GNSS epoch at "
        f"station {g['station']:.0f} m (t={g['t']:.1f} s; {g['left']} / {g['right']} building vertices left / right), "
        f"{n_g} rays = {len(PROBES)} probes + {g['m']} sky + 2 x {g['k']} reflection legs"
    )

    # scene builds (cold meshes), interleaved
    print("\nscene build (construct + first query), median s:")
    for label, mesh in (("charles_river full", river.mesh), ("canal_lock solid", canal_solid), ("canal_lock full", canal.mesh)):
        b = build_rounds(mesh, args.build_rounds)
        ratio = np.median(np.array(b["embree"]) / np.array(b["open3d"]))
        print(f"  {label:20s} open3d {np.median(b['open3d']):6.3f}   embree {np.median(b['embree']):6.3f}   ratio embree/open3d {ratio:5.2f}")

    s_river, e_river = open3d_scene(river.mesh), embree_scene(river.mesh)
    s_solid, e_solid = open3d_scene(canal_solid), embree_scene(canal_solid)
    s_canal, e_canal = open3d_scene(canal.mesh), embree_scene(canal.mesh)
    gr = g["rays"]

    cases = [
        (
            "(a) lidar first",
            n_l,
            args.reps,
            {
                "open3d cast_rays": lambda: o3d_first(s_river, lidar),
                "embree intersects_first": lambda: embree_first(e_river, lidar),
                "embree location(first)": lambda: embree_location(e_river, lidar, False),
                "open3d cast_rays 1 thread": lambda: o3d_first(s_river, lidar, 1),
            },
        ),
        (
            "(b) gnss first",
            n_g,
            args.gnss_reps,
            {
                "open3d cast_rays": lambda: o3d_first(s_solid, gr),
                "embree intersects_first": lambda: embree_first(e_solid, gr),
                "embree location(first)": lambda: embree_location(e_solid, gr, False),
                "open3d cast_rays 1 thread": lambda: o3d_first(s_solid, gr, 1),
            },
        ),
        (
            "(c) lidar multi",
            n_l,
            args.reps,
            {
                "open3d list_intersections": lambda: o3d_multi(s_river, lidar),
                "embree location(multi)": lambda: embree_location(e_river, lidar, True),
                "open3d list_inters. 1 thread": lambda: o3d_multi(s_river, lidar, 1),
            },
        ),
        (
            "(c) gnss multi",
            n_g,
            args.gnss_reps,
            {
                "open3d list_intersections": lambda: o3d_multi(s_canal, gr),
                "embree location(multi)": lambda: embree_location(e_canal, gr, True),
                "open3d list_inters. 1 thread": lambda: o3d_multi(s_canal, gr, 1),
            },
        ),
    ]
    print(f"\n{'query':16s} {'contender':30s} {'median':>10s} {'rays/s':>10s} {'ratio vs open3d':>16s}")
    for label, n, reps, contenders in cases:
        times = rounds(contenders, args.rounds, reps)
        base = np.array(next(iter(times.values())))
        for i, (name, ts) in enumerate(times.items()):
            med = float(np.median(ts))
            unit = f"{med * 1e3:8.2f} ms" if med >= 1e-3 else f"{med * 1e6:8.1f} us"
            ratio = "" if i == 0 else f"{np.median(np.array(ts) / base):6.2f}x time"
            print(f"{label if i == 0 else '':16s} {name:30s} {unit:>10s} {fmt_rate(n, med):>9s}  {ratio:>16s}")

    print("\nagreement, embree vs open3d (same rays):")
    for label, rays, scene, intersector in (("(a) lidar first", lidar, s_river, e_river), ("(b) gnss first", gr, s_solid, e_solid)):
        a = first_agreement(o3d_first(scene, rays), embree_first(intersector, rays), embree_location(intersector, rays, False), len(rays))
        print(
            f"  {label:16s} hit/miss verdict {100 * a['verdict']:.3f}% ({a['n_disagree']} of {len(rays)} rays differ; "
            f"location(first) verdict {100 * a['loc_verdict']:.3f}%), same triangle {100 * a['same_tri']:.3f}% of "
            f"{a['hits']} hits, |dd| max {a['max_dd'] * 1e3:.2f} mm (p99.9 {a['p999_dd'] * 1e3:.2f} mm)"
        )
    v = gnss_verdicts(g, canal_solid, embree_location(e_solid, gr, False))
    print(
        f"  {'':16s} sim.visibility verdicts from embree: los {v['los']}/{v['m']}, reflection clear {v['clear']}/{v['k']}, "
        f"inside-solid {'same' if v['inside'] else 'DIFFERENT'}"
    )
    for label, rays, scene, intersector in (("(c) lidar multi", lidar, s_river, e_river), ("(c) gnss multi", gr, s_canal, e_canal)):
        a = multi_agreement(o3d_multi(scene, rays), embree_location(intersector, rays, True)[:2], len(rays), args.merge_m)
        print(f"  {label:16s} hits open3d {a['hits_o3d']}, embree {a['hits_emb']}")
        for tag in ("raw", "merged"):
            r = a[tag]
            what = "raw" if tag == "raw" else f"hits < {args.merge_m * 100:g} cm apart merged"
            print(
                f"  {'':16s} {what}: same hit count {100 * r['same_count']:.3f}% (open3d more on {r['more_o3d']}, embree "
                f"more on {r['more_emb']} rays), hit/miss verdict {100 * r['verdict']:.3f}%, |dd| on equal-count rays "
                f"max {r['max_dd'] * 1e3:.2f} mm (p99.9 {r['p999_dd'] * 1e3:.2f} mm)"
            )


if __name__ == "__main__":
    main()
