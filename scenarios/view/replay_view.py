"""ReplayView: the replay observer (scenarios.replay.run.ReplayObserver) that logs a replay to rerun as it streams:
`riverbench replay RECORDING --view / --view-save FILE.rrd`.

A replay has no simulated world and no truth, so there is no world mesh, route or hull, no /truth and no GPS error
plot; the entities keep the run's names where they mean the same (scenarios.view.layout). The TIMELINE is the
replay's time (seconds since the recording's time zero: metrics.json's run.recording.time_zero_utc, the time of the
run directory's files). Per scan:
- /estimators/<id>: each estimator's pose that is finite (the <id>.tum rows), with its exact x, y, z, yaw as values;
- /reference (--reference only): the reference's position at the scan where it is defined (an antenna's for a GPX or
  RTK NMEA reference, base_link's for TUM), at the waterline, in the truth's colour; /errors/<id> the estimator's
  horizontal distance to it (from its antenna for an antenna reference), as scenarios.replay.reference scores it;
- /scan: the recorded revolution (points in the lidar frame, as the sensor reports them) placed rigidly at the lidar
  pose of the scan's stamp (world<-base_link times the scenario's mount) and thinned to MAX_SCAN_POINTS. The base_link
  pose is the first estimator (in the scenario's order) whose pose is finite at that scan; with --reference, its
  horizontal position is replaced by the reference's where that is defined (moved from the antenna to base_link by
  that estimator's attitude: a reference gives positions, no attitude). A scan with no finite estimator pose cannot
  be placed: it is logged as recorded, in the lidar frame, under /scan_lidar (drawn about the world origin), so every
  scan is in the view once. The motion during the revolution (0.1 s) is not undone: a real scan's points carry no pose;
- /vessel and /follow: that base_link pose (not logged for a scan that is not placed).
Fixes: /gps/<id>/trusted and .../refused by each estimator's verdict, as a run's view logs them. A GNSS-only replay
(no LiDAR) logs no scan: its pose samples (one after each fix) give the tracks.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import rerun as rr

from scenarios.pipeline.stream import ScanEvent
from scenarios.view.common import TRUTH_COLOUR, ViewBase, thinned
from scenarios.view.layout import TIMELINE
from scenarios.view.sink import ViewSink
from sim.trajectory import mount_matrix

if TYPE_CHECKING:
    from scenarios.replay.reference import Reference
    from scenarios.replay.run import Replaying


class ReplayView(ViewBase):
    """A scenarios.replay.run.ReplayObserver that sends the replay to `sink` (a viewer, a file or both)."""

    def __init__(self, sink: ViewSink, colour_by: str = "height") -> None:
        super().__init__(sink, colour_by)
        self._reference: Reference | None = None  # these four are set by begin(), which the replay calls first
        self._gnss_only = False
        self._mount, self._antenna = np.eye(4), np.zeros(3)

    def begin(self, replaying: Replaying, run_dir: Path) -> None:
        """Open the sinks, send the layout and each series' style (no world: a replay has none)."""
        scenario, recording = replaying.scenario, replaying.recording
        self._open(run_dir, f"replay of {recording.path.name} ({scenario.name})", [e.id for e in scenario.estimators], gps_error=False)
        self._reference, self._gnss_only = replaying.reference, recording.gnss_only
        self._mount = mount_matrix(scenario.vessel)
        self._antenna = np.asarray(scenario.gnss.antenna_offset_m, dtype=float)

    def scan(self, event: ScanEvent, truth: np.ndarray, estimates: dict[str, np.ndarray]) -> None:
        """The scan placed in the world (or in the lidar frame when it cannot be), the vessel, the reference and each
        estimator's pose; `truth` is the Feed's stand-in (a replay has no truth) and unused."""
        self.rec.set_time(TIMELINE, duration=event.stamp)
        reference = self._reference.at(np.array([event.stamp]))[0] if self._reference is not None else None
        base = self.placement(estimates, reference)
        if not self._gnss_only:
            points = thinned(event.scan.points)
            local = np.stack([points["x"], points["y"], points["z"]], axis=1).astype(np.float64)
            if base is None:
                self._log_scan("scan_lidar", local.astype(np.float32), self._values(local, points))
            else:
                lidar = base @ self._mount
                world = local @ lidar[:3, :3].T + lidar[:3, 3]
                self._log_scan("scan", world.astype(np.float32), self._values(world, points))
        if base is not None:
            self._log_vessel(base)
        if reference is None or not np.isfinite(reference).all():
            self._log_estimates(estimates, None)
            return
        values = rr.AnyValues(x=float(reference[0]), y=float(reference[1]))
        self._log_track("reference", np.array([reference[0], reference[1], 0.0]), TRUTH_COLOUR, values)
        self._log_estimates(estimates, lambda pose: float(np.hypot(*(self._reference_point(pose)[:2] - reference))))

    def placement(self, estimates: dict[str, np.ndarray], reference: np.ndarray | None) -> np.ndarray | None:
        """The base_link pose (world<-base_link) the scan is placed at (module docstring), None when there is none."""
        pose = next((p for p in estimates.values() if np.isfinite(p).all()), None)
        if pose is None or reference is None or not np.isfinite(reference).all():
            return pose
        placed = pose.copy()
        placed[:2, 3] = reference - (self._reference_point(pose) - pose[:3, 3])[:2]
        return placed

    def _reference_point(self, pose: np.ndarray) -> np.ndarray:
        """The point of the boat at `pose` that the reference gives: the antenna (GPX, RTK NMEA) or base_link (TUM)."""
        assert self._reference is not None
        return pose[:3, :3] @ self._antenna + pose[:3, 3] if self._reference.point == "antenna" else pose[:3, 3]

    def _values(self, xyz: np.ndarray, points: np.ndarray) -> np.ndarray:
        """What the scan's colour shows: the points' z (world or lidar frame) or their intensity."""
        return xyz[:, 2] if self.colour_by == "height" else points["intensity"]
