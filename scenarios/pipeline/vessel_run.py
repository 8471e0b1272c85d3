"""How the vessel moves in a run, as the scenario's `[control]` says: the planned route (open loop)
or the WAM-V model steered by the autopilot on an estimator's pose (closed loop)."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from scenarios.pipeline.closed_loop import ClosedLoop, autopiloted, watched
from scenarios.pipeline.inertial import with_inertial
from scenarios.pipeline.stream import events as planned_events
from scenarios.score.vessel_log import VesselWatch
from scenarios.spec.scenario import Scenario
from sim.autopilot import Autopilot
from sim.clearance import HullClearance
from sim.compass import Ahrs, with_heading
from sim.driven_trajectory import DrivenTrajectory
from sim.imu import Imu
from sim.magnetic_compass import MagneticCompass
from sim.scan import Scan
from sim.scene import Scene, split
from sim.traffic import build_traffic
from sim.trajectory import Trajectory
from sim.vessel import hull_mesh


@dataclass
class VesselRun:
    """The trajectory the sensors see, the watch that logs clearance, and the events of the run."""

    scenario: Scenario
    world: object  # what the sensors see: a sim.Scene, the world and its traffic
    trajectory: Trajectory | DrivenTrajectory
    watch: VesselWatch
    lidar: object
    receiver: object
    t_start: float
    t_end: float
    loop: ClosedLoop | None = None
    imu: Imu | None = None
    compass: MagneticCompass | None = None

    @classmethod
    def build(cls, scenario: Scenario, world, planned: Trajectory, lidar, receiver, t_start: float, t_end: float) -> VesselRun:
        """Open loop: the planned trajectory. Closed loop: a driven one starting where the plan is at t_start, at its speed.
        The sensors see `world` with the scenario's traffic (a chase boat follows the trajectory the vessel takes)."""
        control = scenario.control
        clearance = HullClearance(world, hull_mesh(scenario.vessel.hull, mast_top_m=0.0))
        if control.mode == "open_loop":
            scene = Scene(world, build_traffic(scenario.traffic, world, planned))
            return cls(scenario, scene, planned, VesselWatch(world, planned, clearance, lidar.revolution_s), lidar, receiver, t_start, t_end)
        start = planned.pose(t_start)
        driven = DrivenTrajectory(
            scenario.vessel.model_copy(update={"seed": scenario.seed}),
            control.dynamics,
            (start[0, 3], start[1, 3], float(np.arctan2(start[1, 0], start[0, 0])), float(planned.speed(t_start))),
            t0=t_start,
            current_enu=control.current_enu_mps,
        )
        watch = VesselWatch(world, driven, clearance, lidar.revolution_s)
        end_station = float(planned.station(t_end))
        t_limit = t_start + control.time_limit_factor * (t_end - t_start)
        scene = Scene(world, build_traffic(scenario.traffic, world, driven, t_start))
        loop = ClosedLoop(scene, driven, lidar, receiver, watch, t_start, end_station, t_limit)
        return cls(scenario, scene, driven, watch, lidar, receiver, t_start, t_end, loop)

    def events(self, feed, cast: Callable[[float], Scan] | None = None) -> Iterator:
        """The run's scans and fixes in time order, with the IMU's and the compass's outputs between them when there are
        such sensors; closed loop steers on `feed`'s estimator (or the truth). `cast(t)`, when given, gives the revolution
        at t (a ScanAhead's in open loop, or one of stamps alone when nothing reads its points)."""
        return with_inertial(self._events(feed, cast), self.trajectory, self.imu, self.compass, self.t_start)

    def _events(self, feed, cast: Callable[[float], Scan] | None) -> Iterator:
        if self.loop is None:
            stream = planned_events(self.world, self.trajectory, self.lidar, self.receiver, self.t_start, self.t_end, cast)
            return watched(stream, self.watch, self.lidar.revolution_s)
        self.loop.cast = cast
        control = self.scenario.control
        autopilot = Autopilot(self.world.route, control.dynamics, self.scenario.vessel.speed_mps, control.autopilot)
        believed = self.trajectory.pose if control.steer_on == "truth" else (lambda t: feed.pose_of(control.steer_on))
        if control.heading == "estimator":
            return autopiloted(self.loop, autopilot, lambda t: (believed(t), None))
        compass = autopilot_heading(self.scenario, self.world, self.compass)

        def steer(t: float) -> tuple[np.ndarray, float]:
            yaw, rate = compass.read(self.trajectory, t, self.t_start)
            return with_heading(believed(t), yaw), rate

        return autopiloted(self.loop, autopilot, steer)


def autopilot_heading(scenario: Scenario, world, compass: MagneticCompass | None = None) -> Ahrs:
    """The autopilot's AHRS: a compass unit of the scenario's [compass] figures (or the defaults) and its gyro; the steel's
    dipoles shared with the estimators' `compass` when there is one (they are the world's)."""
    steel = compass.steel if compass is not None else None
    return Ahrs(split(world)[0], scenario.compass, scenario.control.gyro_sigma_dps, scenario.seed, steel=steel)
