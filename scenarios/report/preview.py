"""The quick-start job until the scenario runner exists: simulate a world along its route, sample
LiDAR revolutions, and write a picture (top view, zoom, 3-D scan view, points-per-revolution
histogram), the densest scan as a PCD file and a JSON summary."""

from __future__ import annotations

import json
import time
from collections import Counter
from dataclasses import asdict, dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import open3d as o3d
from matplotlib.collections import PolyCollection
from rich.progress import track

import worlds
from riverbench.atomic import atomic_dir
from sim import HDL32E, Scan, Trajectory
from worlds.world import World

KIND_COLOURS = {
    "water": "#cfe8ff",
    "wall": "#7f7f7f",
    "quay": "#9e9e9e",
    "bank": "#8fbf6f",
    "bridge_deck": "#d62728",
    "pier": "#8c564b",
    "girder": "#ff7f0e",
    "arch": "#e377c2",
    "lock_wall": "#17becf",
    "lock_gate": "#1f77b4",
    "building": "#4d4d4d",
    "tree": "#6b4226",
    "foliage": "#2ca02c",
    "dock": "#c49c94",
    "pontoon": "#dbdb8d",
    "pile": "#7f7f7f",
    "moored_boat": "#f7f7f7",
    "other": "#bcbd22",
}
BRIDGE_MARGIN_M = 20.0  # revolutions this close to a bridge's GPS shadow count as "under_bridge"
FIELD_STUDY_POINTS = (6_000, 27_000)  # points per revolution at which the study's matching succeeded


@dataclass(frozen=True)
class RevolutionStats:
    """Counts for one simulated revolution along the route."""

    station_m: float
    stamp: float
    n_points: int
    n_water: int
    seconds: float


def sample_route(world: World, n_samples: int, seed: int, quiet: bool) -> tuple[list[RevolutionStats], Scan, Trajectory]:
    """Cast `n_samples` revolutions evenly spaced along the route; return their stats and the densest scan."""
    traj = Trajectory(world, seed=seed)
    lidar = HDL32E(seed=seed)
    stamps = np.linspace(0.0, traj.duration - 2 * lidar.revolution_s, n_samples)
    stats, densest = [], None
    for t0 in track(stamps, description=f"simulating {world.name}", disable=quiet):
        start = time.perf_counter()
        scan = lidar.scan(world, traj, float(t0))
        seconds = time.perf_counter() - start
        n_water = int(world.part_is_water[scan.points["label"]].sum())
        stats.append(RevolutionStats(float(traj.station(t0)), float(t0), len(scan), n_water, seconds))
        if densest is None or len(scan) > len(densest):
            densest = scan
    return stats, densest, traj


def stretch_names(world: World, stations: np.ndarray) -> np.ndarray:
    """Name of the stretch of each route station: 'under_bridge' within BRIDGE_MARGIN_M of a bridge's
    shadow, 'lock' in a lock chamber, else the world's own named stretches (params 'stretches'), else 'open'."""
    stations = np.asarray(stations, dtype=float)
    names = np.full(len(stations), "open", dtype=object)
    for st in world.params.get("stretches", []):
        names[(stations >= st["start_m"]) & (stations < st["end_m"])] = st["name"]
    for st in world.params.get("structures", []):
        if st["type"] == "lock":
            names[(stations >= st["start_m"]) & (stations <= st["end_m"])] = "lock"
        else:
            near = (stations >= st["shadow_start_m"] - BRIDGE_MARGIN_M) & (stations <= st["shadow_end_m"] + BRIDGE_MARGIN_M)
            names[near] = "under_bridge"
    return names


def point_stats(n_points: np.ndarray, n_water: np.ndarray) -> dict:
    """Median, p10, p90 of points per revolution, share in the field study's band, share of water returns."""
    lo, hi = FIELD_STUDY_POINTS
    return {
        "revolutions": len(n_points),
        "median": float(np.median(n_points)),
        "p10": float(np.percentile(n_points, 10)),
        "p90": float(np.percentile(n_points, 90)),
        "share_in_field_study_band": float(np.mean((n_points >= lo) & (n_points <= hi))),
        "water_return_share": float(n_water.sum() / max(n_points.sum(), 1)),
    }


def by_stretch(world: World, stats: list[RevolutionStats]) -> dict[str, dict]:
    """`point_stats` of the revolutions in each stretch (see `stretch_names`), in route order."""
    n = np.array([s.n_points for s in stats])
    water = np.array([s.n_water for s in stats])
    names = stretch_names(world, np.array([s.station_m for s in stats]))
    return {name: point_stats(n[names == name], water[names == name]) for name in dict.fromkeys(names)}


def summarise(world: World, stats: list[RevolutionStats], scan: Scan) -> dict:
    """Summary numbers: world description, points per revolution and water share, overall and by stretch."""
    n = np.array([s.n_points for s in stats])
    water = np.array([s.n_water for s in stats])
    lo, hi = FIELD_STUDY_POINTS
    return {
        "world": worlds.describe(world),
        "revolutions": len(stats),
        "points_per_revolution": {
            "min": int(n.min()),
            "median": float(np.median(n)),
            "p90": float(np.percentile(n, 90)),
            "max": int(n.max()),
        },
        "share_in_field_study_band": float(np.mean((n >= lo) & (n <= hi))),
        "water_return_share": float(water.sum() / max(n.sum(), 1)),
        "by_stretch": by_stretch(world, stats),
        "seconds_per_revolution_median": float(np.median([s.seconds for s in stats])),
        "densest_scan": {
            "stamp": scan.stamp,
            "points": len(scan),
            "by_kind": dict(Counter(world.parts[i].kind for i in scan.points["label"])),
        },
    }


def draw(world: World, traj: Trajectory, stats: list[RevolutionStats], scan: Scan, path: Path) -> None:
    """Top view of the world with route and scan, a zoom on the scan, the scan in 3-D, and a histogram."""
    poses = traj.lidar_poses(scan.stamp + scan.points["time"].astype(np.float64))
    pw = np.einsum("nab,nb->na", poses[:, :3, :3], scan.xyz) + poses[:, :3, 3]
    centre = traj.pose(scan.stamp)[:2, 3]
    fig = plt.figure(figsize=(16, 12))
    top = fig.add_subplot(2, 2, 1)
    zoom = fig.add_subplot(2, 2, 2)
    view3d = fig.add_subplot(2, 2, 3, projection="3d")
    hist = fig.add_subplot(2, 2, 4)
    for ax in (top, zoom):
        _draw_parts(ax, world)
        ax.plot(*world.route.xy.T, color="k", lw=0.8, ls="--", label="route")
        ax.set_aspect("equal")
        ax.set_xlabel("east (m)")
        ax.set_ylabel("north (m)")
    top.scatter(pw[::20, 0], pw[::20, 1], s=0.5, c="m")
    top.set_title(f"{world.name}: top view, route and one scan")
    zoom.scatter(pw[:, 0], pw[:, 1], s=0.3, c=pw[:, 2], cmap="viridis")
    zoom.set_xlim(centre[0] - 110, centre[0] + 110)
    zoom.set_ylim(centre[1] - 110, centre[1] + 110)
    zoom.set_title(f"scan at t = {scan.stamp:.1f} s: {len(scan)} points, coloured by height")
    local = scan.xyz
    view3d.scatter(local[:, 0], local[:, 1], local[:, 2], s=0.2, c=local[:, 2], cmap="viridis")
    view3d.set_title("the same scan in the lidar frame (3-D)")
    view3d.set_box_aspect((1, 1, 0.3))
    n = [s.n_points for s in stats]
    hist.hist(n, bins=30, color="tab:blue")
    for edge in FIELD_STUDY_POINTS:
        hist.axvline(edge, color="tab:red", ls=":")
    hist.set_xlabel("points per revolution")
    hist.set_ylabel("revolutions")
    hist.set_title("points per revolution along the route (red: the field study's 6k-27k band)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _draw_parts(ax, world: World) -> None:
    for part in world.parts:
        tri = part.mesh.vertices[part.mesh.faces][:, :, :2]
        a, b = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        area = np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0])
        ax.add_collection(PolyCollection(tri[area > 1e-6], facecolors=KIND_COLOURS[part.kind], edgecolors="none"))
    ax.autoscale_view()


def write_pcd(scan: Scan, path: Path) -> None:
    """The scan as a PCD with intensity, ring and time, readable by PCL, Open3D and CloudCompare."""
    cloud = o3d.t.geometry.PointCloud(o3d.core.Tensor(scan.xyz.astype(np.float32)))
    for field in ("intensity", "time"):
        cloud.point[field] = o3d.core.Tensor(np.ascontiguousarray(scan.points[field]).reshape(-1, 1))
    cloud.point["ring"] = o3d.core.Tensor(scan.points["ring"].astype(np.int32).reshape(-1, 1))
    if not o3d.t.io.write_point_cloud(str(path), cloud):
        raise OSError(f"could not write {path}")


def run_preview(world_name: str, out_dir: Path, n_samples: int = 60, seed: int = 0, quiet: bool = False) -> dict:
    """Simulate `world_name`, write preview.png, scan.pcd and summary.json into out_dir; return the summary."""
    world = worlds.load(world_name)
    stats, scan, traj = sample_route(world, n_samples, seed, quiet)
    summary = summarise(world, stats, scan)
    with atomic_dir(out_dir) as tmp:
        draw(world, traj, stats, scan, tmp / "preview.png")
        write_pcd(scan, tmp / "scan.pcd")
        (tmp / "revolutions.json").write_text(json.dumps([asdict(s) for s in stats], indent=1))
        (tmp / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
    return summary
