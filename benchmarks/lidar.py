"""LiDAR throughput on charles_river: revolutions per second of the full HDL-32E pipeline (rays,
ray cast, noise, intensity, drop-outs, timestamps) against a bare Open3D RaycastingScene cast of the
same number of rays in the same run, their ratio, the same pipeline with moving boats around the
ASV (each seen at every ray's firing time) against the static one, and peak memory. Prints medians
over rounds.

    .venv/bin/python benchmarks/lidar.py [--world charles_river] [--rounds 7] [--revs 40]
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np
import open3d as o3d

import worlds
from sim import HDL32E, Scene, Traffic, Trajectory
from sim.boats import boat
from sim.movers import Chase, Mover

ESCORT = (("chase", "runabout", 15.0, -6.0), ("ahead", "cruiser", -30.0, 12.0), ("abeam", "cruiser", 0.0, -18.0), ("barge", "barge", -55.0, -15.0))
"""Boats that keep their place around the ASV (id, kind, metres behind, metres to its left), so every
revolution along the route has them in view: the costly case (crossing or passing boats are in view
only for a while)."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="charles_river")
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--revs", type=int, default=40, help="revolutions per round")
    parser.add_argument("--movers", type=int, default=4, choices=range(1, len(ESCORT) + 1), help="boats around the ASV")
    args = parser.parse_args()

    t_load = time.perf_counter()
    world = worlds.load(args.world)
    traj = Trajectory(world)
    lidar = HDL32E()
    scene = world.raycasting_scene
    load_s = time.perf_counter() - t_load
    traffic = Traffic(tuple(Mover(name, *boat(kind), Chase(traj, behind, left)) for name, kind, behind, left in ESCORT[: args.movers]))
    moving = Scene(world, traffic)
    rss_world_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    # revolutions spread along the whole route, so every kind of structure is in the mix
    stamps = np.linspace(0.0, traj.duration - 1.0, args.rounds * args.revs).reshape(args.rounds, args.revs)
    lidar.scan(moving, traj, stamps[0, 0])  # warm up: self-occlusion mask, scene builds

    full_hz, bare_hz, moving_hz, points, mover_points = [], [], [], [], []
    for row in stamps:
        # the bare cast gets exactly the rays the pipeline casts, built before its clock starts
        bare_rays = [o3d.core.Tensor(lidar.rays(traj, float(t0))) for t0 in row]
        start = time.perf_counter()
        for rays in bare_rays:
            scene.cast_rays(rays)
        bare_hz.append(len(row) / (time.perf_counter() - start))
        start = time.perf_counter()
        for t0 in row:
            points.append(len(lidar.scan(world, traj, float(t0))))
        full_hz.append(len(row) / (time.perf_counter() - start))
        start = time.perf_counter()
        for t0 in row:
            mover_points.append(int((lidar.scan(moving, traj, float(t0)).points["label"] >= len(world.parts)).sum()))
        moving_hz.append(len(row) / (time.perf_counter() - start))
    ratios = np.array(full_hz) / np.array(bare_hz)
    moving_ratios = np.array(moving_hz) / np.array(full_hz)
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    n_rays = lidar.n_firings * 32
    print(f"world {args.world}: {len(world.mesh.faces)} triangles, load {load_s:.2f} s")
    print(f"rays per revolution: {n_rays}; rounds {args.rounds} x {args.revs} revolutions")
    print(f"full pipeline:  median {np.median(full_hz):7.1f} rev/s  (min {min(full_hz):.1f}, max {max(full_hz):.1f})")
    print(f"bare cast:      median {np.median(bare_hz):7.1f} rev/s  (min {min(bare_hz):.1f}, max {max(bare_hz):.1f})")
    print(f"ratio full/bare (per round, same run): median {np.median(ratios):.2f}")
    print(f"with {len(traffic)} movers:  median {np.median(moving_hz):7.1f} rev/s  (min {min(moving_hz):.1f}, max {max(moving_hz):.1f})")
    print(
        f"ratio movers/static (per round, same run): median {np.median(moving_ratios):.2f} (goal >= 0.80); "
        f"mover points per revolution: median {np.median(mover_points):.0f}, max {max(mover_points)}"
    )
    print(
        f"points per revolution: median {np.median(points):.0f}, p10 {np.percentile(points, 10):.0f}, "
        f"p90 {np.percentile(points, 90):.0f}, max {max(points)}"
    )
    print(f"peak RSS: {peak_mb:.0f} MB (after loading the world: {rss_world_mb:.0f} MB)")


if __name__ == "__main__":
    main()
