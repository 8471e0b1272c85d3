"""The viewer's panels for a run: the scan in its world following the vessel, the tracks and GPS fixes so far, the errors.

Entity paths (what scenarios.view.live logs):
  /world/<part>                     the world's meshes (static), /world/route the route (static)
  /vessel                           the true base_link pose (a transform) and /vessel/hull its box
  /follow                           the vessel's position and heading (no roll, pitch): the scene view's frame
  /scan                             the current revolution in world ENU, coloured by height or intensity
  /truth, /estimators/<id>          one point per scan (the tracks), with the exact x, y, z, yaw as values
  /gps/<id>/trusted, .../refused    each fix where the receiver put it, by that estimator's monitor's verdict
  /errors/<id>, /errors/gps         horizontal error against the truth (m): each estimator per scan, each measured fix
A replay (scenarios.view.replay_view) has no world and no truth: it logs /scan (placed at an estimate), /scan_lidar
(a scan it cannot place, in the lidar frame), /vessel, /follow, /estimators/<id>, /gps/..., and with --reference
/reference (the reference's position) and /errors/<id> (each estimator's horizontal distance to it).
"""

from __future__ import annotations

import rerun.blueprint as rrb

TIMELINE = "sim_time"
"""The view's time line: seconds since the scenario's start (a replay's: since the recording's time zero), the time of the
run directory's files."""
EYE = (-40.0, 0.0, 25.0)
"""The scene's eye in /follow's frame: behind the vessel and above the water, so it chases the vessel."""
LOOK_AT = (15.0, 0.0, 0.0)
"""Where the eye looks in /follow's frame: just ahead of the vessel."""


def blueprint() -> rrb.Blueprint:
    """Left: the scene now (world, scan, vessel, poses; a replay's reference) in /follow's frame, the eye chasing the vessel.
    Right: every track and fix up to the time cursor (one point per step, accumulated by the view's time range) above the
    error plot."""
    so_far = rrb.VisibleTimeRange(TIMELINE, start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.cursor_relative())
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(
                name="scan and world",
                origin="/follow",
                contents=["+ /world/**", "+ /vessel/**", "+ /scan", "+ /scan_lidar", "+ /truth", "+ /reference", "+ /estimators/**"],
                eye_controls=rrb.EyeControls3D(position=EYE, look_target=LOOK_AT, eye_up=(0.0, 0.0, 1.0)),
            ),
            rrb.Vertical(
                rrb.Spatial3DView(
                    name="tracks and GPS fixes so far",
                    origin="/",
                    contents=["+ /truth", "+ /reference", "+ /estimators/**", "+ /gps/**"],
                    time_ranges=so_far,
                ),
                rrb.TimeSeriesView(name="horizontal error (m)", origin="/errors"),
            ),
            column_shares=[3, 2],
        ),
        rrb.TimePanel(timeline=TIMELINE),
    )
