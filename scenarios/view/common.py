"""What a run's view (scenarios.view.live) and a replay's (scenarios.view.replay_view) share: the styles, and ViewBase,
which opens the recording and logs a scan's points, the vessel, a track point, the estimators' poses and the fixes by verdict.

Everything is stamped on the TIMELINE (seconds since the scenario's start, or a replay's time zero), so the viewer
scrubs through the run; the entities are listed in scenarios.view.layout.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import matplotlib
import numpy as np
import rerun as rr

from fusion.observation import POSITION_QUALITIES
from fusion.verdict import Verdict
from scenarios.view.layout import TIMELINE, blueprint
from scenarios.view.sink import ViewSink
from sim.gnss_fix import GnssFix

COLOUR_BY = ("height", "intensity")
"""What the scan's colour shows: height above the water (world z) or the intensity (simulated or as the sensor reports it)."""
HEIGHT_RANGE_M = (-1.0, 15.0)
"""World z mapped onto the colour map: the water (z = 0, waves below it) up to above the bridge decks."""
INTENSITY_RANGE = (0.0, 100.0)
"""Intensity mapped onto the colour map: sim.lidar reports 100 x reflectivity x incidence cosine x attenuation,
so 100 is a perfect reflector met head-on (a Velodyne's calibrated reflectivity: 0-100 diffuse, above it retro-reflectors)."""
MAX_SCAN_POINTS = 10_000
"""Points of a scan in the view (every k-th point beyond): bounds what a scan costs the run and the recording."""
TURBO_PART = (0.4, 1.0)
"""The part of matplotlib's turbo colour map the scan uses: green to red, no blue to vanish on the water."""
SCAN_RADIUS, TRACK_RADIUS, FIX_RADIUS = (rr.components.Radius.ui_points(px) for px in (2.5, 3.0, 4.0))
"""Drawn sizes in screen points, whatever the zoom."""
TRUTH_COLOUR = (255, 255, 255)
"""The truth of a run, the reference of a replay (--reference): what the estimators are scored against."""
TRUSTED_COLOUR = (44, 160, 44)
REFUSED_COLOUR = (214, 39, 40)
GPS_ERROR_COLOUR = (160, 160, 160)
ESTIMATOR_COLOURS = [(31, 119, 180), (255, 127, 14), (148, 103, 189), (23, 190, 207), (227, 119, 194), (188, 189, 34), (140, 86, 75)]
"""Tab10 without its green, red and grey (kept for the verdicts and the GPS error); cycled over the estimators."""


class ViewBase:
    """The parts of a scenarios.pipeline.observer.RunObserver that send to `sink` (a viewer, a file or both) and need no world."""

    def __init__(self, sink: ViewSink, colour_by: str = "height") -> None:
        if colour_by not in COLOUR_BY:
            raise ValueError(f"--view-colour {colour_by!r}: use {' or '.join(COLOUR_BY)}")
        self.sink, self.rec, self.colour_by = sink, sink.rec, colour_by
        self._lut = (matplotlib.colormaps["turbo"](np.linspace(*TURBO_PART, 256))[:, :3] * 255).astype(np.uint8)
        self._colours: dict[str, tuple[int, int, int]] = {}

    def _open(self, run_dir: Path, name: str, estimator_ids: list[str], gps_error: bool) -> None:
        """Open the sinks into `run_dir`, name the recording, send the layout, each estimator's colour and error series, and
        the GPS error's when there is one to plot (a run's: the fixes' true error)."""
        self.sink.attach(run_dir)
        rec = self.rec
        rec.send_recording_name(name)
        rec.send_blueprint(blueprint())
        self._colours = {eid: ESTIMATOR_COLOURS[i % len(ESTIMATOR_COLOURS)] for i, eid in enumerate(estimator_ids)}
        for eid, colour in self._colours.items():
            rec.log(f"errors/{eid}", rr.SeriesLines(colors=[colour], names=[eid]), static=True)
        if gps_error:
            rec.log("errors/gps", rr.SeriesPoints(colors=[GPS_ERROR_COLOUR], names=["GPS fix"], marker_sizes=[2.0]), static=True)

    def fix(self, fix: GnssFix, verdicts: dict[str, Verdict]) -> None:
        """Where the receiver put the fix, once per estimator under its monitor's verdict; its true horizontal error (a run's)."""
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

    def _log_scan(self, entity: str, points: np.ndarray, values: np.ndarray) -> None:
        """(N, 3) points coloured by `values` (world z or intensity) on the colour map."""
        lo, hi = HEIGHT_RANGE_M if self.colour_by == "height" else INTENSITY_RANGE
        index = np.clip((np.asarray(values, dtype=np.float64) - lo) / (hi - lo) * 255.0, 0, 255).astype(np.intp)
        self.rec.log(entity, rr.Points3D(points, colors=self._lut[index], radii=SCAN_RADIUS))

    def _log_vessel(self, pose: np.ndarray) -> None:
        """The vessel's frame at `pose` (world<-base_link) and /follow, its position and heading (the scene view's frame)."""
        rec = self.rec
        rec.log("vessel", rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]))
        heading = rr.RotationAxisAngle(axis=(0.0, 0.0, 1.0), radians=math.atan2(pose[1, 0], pose[0, 0]))
        rec.log("follow", rr.Transform3D(translation=pose[:3, 3], rotation_axis_angle=heading))

    def _log_track(self, entity: str, position: np.ndarray, colour: tuple[int, int, int], values: rr.AnyValues) -> None:
        """One point of a track, with its exact numbers as values."""
        self.rec.log(entity, rr.Points3D([position], colors=[colour], radii=TRACK_RADIUS), values)

    def _log_estimates(self, estimates: dict[str, np.ndarray], error: Callable[[np.ndarray], float] | None) -> None:
        """Each estimator's pose that is finite as a track point, and its horizontal `error(pose)` when that is finite."""
        for eid, pose in estimates.items():
            if not np.isfinite(pose).all():
                continue  # not initialised yet, or failed: nothing to draw
            self._log_track(f"estimators/{eid}", pose[:3, 3], self._colours.get(eid, ESTIMATOR_COLOURS[0]), pose_values(pose))
            value = error(pose) if error is not None else math.nan
            if math.isfinite(value):
                self.rec.log(f"errors/{eid}", rr.Scalars(value))


def thinned(points: np.ndarray) -> np.ndarray:
    """Every k-th point of a scan, k the smallest that keeps at most MAX_SCAN_POINTS."""
    return points[:: max(1, math.ceil(len(points) / MAX_SCAN_POINTS))]


def pose_values(pose: np.ndarray) -> rr.AnyValues:
    """The pose's exact numbers (float64: the drawn points are float32, ~0.2 mm at 3 km from the origin)."""
    return rr.AnyValues(x=float(pose[0, 3]), y=float(pose[1, 3]), z=float(pose[2, 3]), yaw=math.atan2(pose[1, 0], pose[0, 0]))
