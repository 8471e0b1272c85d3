"""LiveView: the run observer that logs the run to rerun as it streams (the entities are listed in scenarios.view.layout).

Everything is stamped on the TIMELINE (seconds since the scenario's start), so the viewer scrubs through
the run. The scan is put in the world frame point by point (each point at its firing time's pose, as the
simulator cast it) and thinned to MAX_SCAN_POINTS; the world is logged once (scenarios.view.world_mesh).
What needs no world (the fixes by verdict, the estimators' tracks, the styles) is scenarios.view.common's.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import rerun as rr

from scenarios.pipeline.assembly import Assembly
from scenarios.pipeline.stream import ScanEvent
from scenarios.view.common import TRUTH_COLOUR, ViewBase, pose_values, thinned
from scenarios.view.layout import TIMELINE
from scenarios.view.sink import ViewSink
from scenarios.view.world_mesh import part_meshes
from sim.trajectory import VesselPoses

POSE_KNOTS = 36
"""Poses per revolution between which a point's pose is interpolated (every 10 deg of azimuth, 2.8 ms at 10 Hz)."""
ROUTE_COLOUR = (120, 120, 120)


class LiveView(ViewBase):
    """A scenarios.pipeline.observer.RunObserver that sends the run to `sink` (a viewer, a file or both)."""

    def __init__(self, sink: ViewSink, colour_by: str = "height") -> None:
        super().__init__(sink, colour_by)
        self._trajectory: VesselPoses | None = None  # set by begin(), which the run calls first
        self._revolution_s = math.nan

    def begin(self, stack: Assembly, run_dir: Path) -> None:
        """Open the sinks, send the layout, then the static scene: the world, the route, the hull and each series' style."""
        rec, scenario = self.rec, stack.scenario
        self._open(run_dir, f"{scenario.name} (seed {scenario.seed})", [e.id for e in scenario.estimators], gps_error=True)
        self._trajectory, self._revolution_s = stack.trajectory, stack.lidar.revolution_s
        for part in part_meshes(stack.world):
            rec.log(
                f"world/{part.name}",
                rr.Mesh3D(vertex_positions=part.vertices, triangle_indices=part.faces, vertex_normals=part.normals, albedo_factor=part.colour),
                static=True,
            )
        route = stack.world.route.xy
        rec.log("world/route", rr.LineStrips3D([np.column_stack([route, np.zeros(len(route))])], colors=[ROUTE_COLOUR]), static=True)
        lo, hi = stack.trajectory.hull.bounds
        rec.log("vessel/hull", rr.Boxes3D(centers=[(lo + hi) / 2], half_sizes=[(hi - lo) / 2], colors=[TRUTH_COLOUR]), static=True)

    def scan(self, event: ScanEvent, truth: np.ndarray, estimates: dict[str, np.ndarray]) -> None:
        """The scan in the world frame, the vessel, the true pose and each estimator's, and their errors."""
        self.rec.set_time(TIMELINE, duration=event.stamp)
        self._log_scan("scan", *self._world_points(event))
        self._log_vessel(truth)
        self._log_track("truth", truth[:3, 3], TRUTH_COLOUR, pose_values(truth))
        self._log_estimates(estimates, lambda pose: float(np.hypot(*(pose[:2, 3] - truth[:2, 3]))))

    def _world_points(self, event: ScanEvent) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) float32 world ENU points of the scan thinned to MAX_SCAN_POINTS, and the value its colour shows."""
        assert self._trajectory is not None, "begin() first"
        points = thinned(event.scan.points)
        knot_t = np.linspace(0.0, self._revolution_s, POSE_KNOTS + 1)
        knots = self._trajectory.lidar_poses(event.stamp + knot_t)
        u = np.clip(points["time"].astype(np.float64) / self._revolution_s * POSE_KNOTS, 0.0, POSE_KNOTS - 1e-9)
        i = u.astype(np.intp)
        frac = (u - i)[:, None, None]
        poses = knots[i] + frac * (knots[i + 1] - knots[i])  # linear between knots, as sim.lidar interpolates its firing poses
        local = np.stack([points["x"], points["y"], points["z"]], axis=1).astype(np.float64)
        world = np.einsum("nij,nj->ni", poses[:, :3, :3], local) + poses[:, :3, 3]
        values = world[:, 2] if self.colour_by == "height" else points["intensity"]
        return world.astype(np.float32), values
