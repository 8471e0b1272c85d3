"""LiveView: the run observer that logs the run to rerun as it streams (the entities are listed in scenarios.view.layout).

Everything is stamped on the TIMELINE (seconds since the scenario's start), so the viewer scrubs through
the run. The scan is put in the world frame point by point (each point at its firing time's pose, as the
simulator cast it) and thinned to MAX_SCAN_POINTS; the world is logged once (scenarios.view.world_mesh).
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib
import numpy as np
import rerun as rr

from fusion.observation import POSITION_QUALITIES
from fusion.verdict import Verdict
from scenarios.pipeline.assembly import Assembly
from scenarios.pipeline.stream import ScanEvent
from scenarios.view.layout import TIMELINE, blueprint
from scenarios.view.sink import ViewSink
from scenarios.view.world_mesh import part_meshes
from sim.gnss_fix import GnssFix
from sim.trajectory import VesselPoses

COLOUR_BY = ("height", "intensity")
"""What the scan's colour shows: height above the water (world z) or the simulated intensity."""
HEIGHT_RANGE_M = (-1.0, 15.0)
"""World z mapped onto the colour map: the water (z = 0, waves below it) up to above the bridge decks."""
INTENSITY_RANGE = (0.0, 100.0)
"""Intensity mapped onto the colour map: sim.lidar reports 100 x reflectivity x incidence cosine x attenuation,
so 100 is a perfect reflector met head-on."""
MAX_SCAN_POINTS = 10_000
"""Points of a scan in the view (every k-th point beyond): bounds what a scan costs the run and the recording."""
POSE_KNOTS = 36
"""Poses per revolution between which a point's pose is interpolated (every 10 deg of azimuth, 2.8 ms at 10 Hz)."""
TURBO_PART = (0.4, 1.0)
"""The part of matplotlib's turbo colour map the scan uses: green to red, no blue to vanish on the water."""
SCAN_RADIUS, TRACK_RADIUS, FIX_RADIUS = (rr.components.Radius.ui_points(px) for px in (2.5, 3.0, 4.0))
"""Drawn sizes in screen points, whatever the zoom."""
TRUTH_COLOUR = (255, 255, 255)
ROUTE_COLOUR = (120, 120, 120)
TRUSTED_COLOUR = (44, 160, 44)
REFUSED_COLOUR = (214, 39, 40)
GPS_ERROR_COLOUR = (160, 160, 160)
ESTIMATOR_COLOURS = [(31, 119, 180), (255, 127, 14), (148, 103, 189), (23, 190, 207), (227, 119, 194), (188, 189, 34), (140, 86, 75)]
"""Tab10 without its green, red and grey (kept for the verdicts and the GPS error); cycled over the estimators."""


class LiveView:
    """A scenarios.pipeline.observer.RunObserver that sends the run to `sink` (a viewer, a file or both)."""

    def __init__(self, sink: ViewSink, colour_by: str = "height") -> None:
        if colour_by not in COLOUR_BY:
            raise ValueError(f"--view-colour {colour_by!r}: use {' or '.join(COLOUR_BY)}")
        self.sink, self.rec, self.colour_by = sink, sink.rec, colour_by
        self._lut = (matplotlib.colormaps["turbo"](np.linspace(*TURBO_PART, 256))[:, :3] * 255).astype(np.uint8)
        self._trajectory: VesselPoses | None = None  # set by begin(), which the run calls first
        self._revolution_s = math.nan
        self._colours: dict[str, tuple[int, int, int]] = {}

    def begin(self, stack: Assembly, run_dir: Path) -> None:
        """Open the sinks, send the layout, then the static scene: the world, the route, the hull and each series' style."""
        self.sink.attach(run_dir)
        rec, scenario = self.rec, stack.scenario
        rec.send_recording_name(f"{scenario.name} (seed {scenario.seed})")
        rec.send_blueprint(blueprint())
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
        self._colours = {e.id: ESTIMATOR_COLOURS[i % len(ESTIMATOR_COLOURS)] for i, e in enumerate(scenario.estimators)}
        for eid, colour in self._colours.items():
            rec.log(f"errors/{eid}", rr.SeriesLines(colors=[colour], names=[eid]), static=True)
        rec.log("errors/gps", rr.SeriesPoints(colors=[GPS_ERROR_COLOUR], names=["GPS fix"], marker_sizes=[2.0]), static=True)

    def scan(self, event: ScanEvent, truth: np.ndarray, estimates: dict[str, np.ndarray]) -> None:
        """The scan in the world frame, the vessel, the true pose and each estimator's, and their errors."""
        rec = self.rec
        rec.set_time(TIMELINE, duration=event.stamp)
        points, values = self._world_points(event)
        rec.log("scan", rr.Points3D(points, colors=self._lut[self._colour_index(values)], radii=SCAN_RADIUS))
        rec.log("vessel", rr.Transform3D(translation=truth[:3, 3], mat3x3=truth[:3, :3]))
        heading = rr.RotationAxisAngle(axis=(0.0, 0.0, 1.0), radians=math.atan2(truth[1, 0], truth[0, 0]))
        rec.log("follow", rr.Transform3D(translation=truth[:3, 3], rotation_axis_angle=heading))
        rec.log("truth", rr.Points3D([truth[:3, 3]], colors=[TRUTH_COLOUR], radii=TRACK_RADIUS), _pose_values(truth))
        for eid, pose in estimates.items():
            if not np.isfinite(pose).all():
                continue  # not initialised yet, or failed: nothing to draw
            colour = self._colours.get(eid, ESTIMATOR_COLOURS[0])
            rec.log(f"estimators/{eid}", rr.Points3D([pose[:3, 3]], colors=[colour], radii=TRACK_RADIUS), _pose_values(pose))
            rec.log(f"errors/{eid}", rr.Scalars(float(np.hypot(*(pose[:2, 3] - truth[:2, 3])))))

    def fix(self, fix: GnssFix, verdicts: dict[str, Verdict]) -> None:
        """Where the receiver put the fix, once per estimator under its monitor's verdict; its true horizontal error."""
        if not np.isfinite(fix.enu).all():
            return  # no position (GGA quality 0)
        rec = self.rec
        rec.set_time(TIMELINE, duration=fix.stamp)
        for eid, verdict in verdicts.items():
            trusted = bool(verdict.trusted)
            rec.log(
                f"gps/{eid}/{'trusted' if trusted else 'refused'}",
                rr.Points3D([fix.enu], colors=[TRUSTED_COLOUR if trusted else REFUSED_COLOUR], radii=FIX_RADIUS),
                rr.AnyValues(statistic=float(verdict.statistic), reason=str(verdict.reason)),
            )
        if fix.truth is not None and fix.quality in POSITION_QUALITIES:
            rec.log("errors/gps", rr.Scalars(float(np.hypot(fix.truth.error[0], fix.truth.error[1]))))

    def close(self, keep: bool) -> None:
        self.sink.close(keep)

    def _world_points(self, event: ScanEvent) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) float32 world ENU points of the scan thinned to MAX_SCAN_POINTS, and the value its colour shows."""
        assert self._trajectory is not None, "begin() first"
        points = event.scan.points
        step = max(1, math.ceil(len(points) / MAX_SCAN_POINTS))
        points = points[::step]
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

    def _colour_index(self, values: np.ndarray) -> np.ndarray:
        """Each value's entry in the colour map (clipped to the ends of its range)."""
        lo, hi = HEIGHT_RANGE_M if self.colour_by == "height" else INTENSITY_RANGE
        return np.clip((np.asarray(values, dtype=np.float64) - lo) / (hi - lo) * 255.0, 0, 255).astype(np.intp)


def _pose_values(pose: np.ndarray) -> rr.AnyValues:
    """The pose's exact numbers (float64: the drawn points are float32, ~0.2 mm at 3 km from the origin)."""
    return rr.AnyValues(x=float(pose[0, 3]), y=float(pose[1, 3]), z=float(pose[2, 3]), yaw=math.atan2(pose[1, 0], pose[0, 0]))
