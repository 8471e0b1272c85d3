"""The one assembly of a scenario's stack: world, sensors and vessel for a simulated stretch, and the recorder and matcher
setups every consumer (run, replay, export, gym episode) feeds; built here once so they cannot drift apart."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

import sim
import worlds
from scenarios.pipeline.matcher_pool import MatcherSetup
from scenarios.pipeline.vessel_run import VesselRun
from scenarios.score.record import Recorder
from scenarios.spec.scenario import Scenario
from sim.imu import Imu
from sim.magnetic_compass import MagneticCompass
from sim.trajectory import mount_matrix


@dataclass
class Assembly:
    """A simulated scenario ready to stream: its world, LiDAR, GNSS receiver, the vessel's run (open or closed loop) and
    the stretch's start and end times on the trajectory."""

    scenario: Scenario
    world: worlds.World
    lidar: sim.HDL32E
    receiver: sim.GnssReceiver
    vessel_run: VesselRun
    t_start: float
    t_end: float

    @property
    def trajectory(self):
        """The vessel's trajectory as it is sailed (planned, or driven by the autopilot in closed loop)."""
        return self.vessel_run.trajectory

    def recorder(self) -> Recorder:
        """A recorder of this scenario's matchers and estimators at the vessel's lidar mount."""
        return recorder(self.scenario, self.trajectory.mount)


def assemble(scenario: Scenario, world: worlds.World | None = None) -> Assembly:
    """World (loaded unless given: a gym env reuses its own), sensors and vessel of `scenario`, seeded by scenario.seed."""
    world = world if world is not None else worlds.load(scenario.world, **scenario.world_params)
    planned = sim.Trajectory(world, seed=scenario.seed, **scenario.vessel.model_dump(exclude={"seed"}))
    lidar = sim.HDL32E(
        seed=scenario.seed,
        **scenario.lidar.model_dump(exclude={"seed", "rate_hz", "range_noise_m"}),
        rate_hz=scenario.lidar.rate_hz,
        range_noise_m=scenario.lidar.range_noise_m,
    )
    receiver = sim.GnssReceiver(seed=scenario.seed, **scenario.gnss.model_dump(exclude={"rate_hz"}), rate_hz=scenario.gnss.rate_hz)
    t_start, t_end = scenario.stretch.times(planned)
    receiver.check_covers(t_start, t_end)  # a stretch beyond the ephemeris file: one line before anything runs
    vessel_run = VesselRun.build(scenario, world, planned, lidar, receiver, t_start, t_end)
    # the IMU and the compass exist only when an estimator is fed them (the default stack simulates neither)
    if scenario.imu is not None:
        vessel_run.imu = Imu(scenario.imu, seed=scenario.seed, origin_lat_deg=world.origin[0])
    if scenario.compass is not None:
        vessel_run.compass = MagneticCompass(world, scenario.compass, seed=scenario.seed)
    return Assembly(scenario, world, lidar, receiver, vessel_run, t_start, t_end)


def recorder(scenario: Scenario, mount: np.ndarray | None = None) -> Recorder:
    """A recorder of the scenario's matchers and estimators; `mount` base_link<-lidar, default the scenario's [vessel] mount."""
    return Recorder([m.id for m in scenario.matchers], [e.id for e in scenario.estimators], mount_matrix(scenario.vessel) if mount is None else mount)


def matcher_setups(scenario: Scenario) -> list[MatcherSetup]:
    """What the matcher pool builds each of the scenario's matchers from."""
    return [MatcherSetup(m.id, m.ref, m.params) for m in scenario.matchers]
