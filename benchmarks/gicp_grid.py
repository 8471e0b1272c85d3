"""gicp's along-track step error against the exact truth with its voxel grid fixed to the sensor (the default, as
small_gicp's preprocess_points and PCL's VoxelGrid do) and carried with the scene (`voxel_grid = "scene"`), on
stretches of charles_river: median and standard deviation of (estimated - true) forward step per match, in mm.

    .venv/bin/python benchmarks/gicp_grid.py [--seed 0] [--stretch START:END:FIRST:COUNT ...]

A stretch's matches are those of revolutions FIRST to FIRST + COUNT - 1 of the stretch (the lock road's walls and deck
begin 25 m into 4715-4760 m).
"""

from __future__ import annotations

import argparse

import numpy as np

import matcher
from scenarios.pipeline.assembly import assemble
from scenarios.pipeline.stream import scan_times
from scenarios.spec.library import validate

STRETCHES = ("300:400:20:100", "1650:1750:20:100", "2900:3000:20:100", "3170:3250:20:60", "4100:4200:20:100", "4715:4760:100:40")
"""The open basin, the basin's far side, before and under the Longfellow Bridge's ribs, the lower basin, the lock's road."""


def step_errors(start_m: float, end_m: float, seed: int, first: int, count: int, grid: str) -> np.ndarray:
    """(estimated - true) forward step of every good match of revolutions first .. first + count - 1 of the stretch, m."""
    scenario = validate(
        {"name": "gicp_grid", "world": "charles_river", "seed": seed, "stretch": {"start_m": start_m, "end_m": end_m}, "estimators": []}
    )
    stack = assemble(scenario)
    lidar, trajectory, world = stack.lidar, stack.trajectory, stack.vessel_run.world
    stamps = scan_times(lidar, stack.t_start, stack.t_end)[first : first + count]
    m = matcher.create("gicp", voxel_grid=grid)
    errors = []
    for t in stamps:
        scan = lidar.scan(world, trajectory, float(t))
        r = m.register(scan)
        ref = r.info.get("ref_stamp")
        if r.ok and ref is not None:
            truth = np.linalg.solve(trajectory.lidar_pose(float(ref)), trajectory.lidar_pose(scan.stamp))
            errors.append(r.T[0, 3] - truth[0, 3])
    return np.array(errors)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--stretch", nargs="+", default=list(STRETCHES), help="START:END:FIRST:COUNT (metres of route, revolutions)")
    args = parser.parse_args()
    print(f"charles_river seed {args.seed}; forward step error of each match against the truth, mm")
    print(f"{'stretch m':>11} {'matches':>7} {'sensor median':>13} {'sd':>6} {'scene median':>12} {'sd':>6}")
    for stretch in args.stretch:
        start, end, first, count = stretch.split(":")
        sensor, scene = (1e3 * step_errors(float(start), float(end), args.seed, int(first), int(count), grid) for grid in ("sensor", "scene"))
        print(
            f"{stretch:>11} {len(scene):7d} {np.median(sensor):+13.1f} {sensor.std():6.1f} {np.median(scene):+12.1f} {scene.std():6.1f}", flush=True
        )


if __name__ == "__main__":
    main()
