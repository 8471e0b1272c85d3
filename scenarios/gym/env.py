"""RiverNav-v0: steer a WAM-V along a river stretch on what its estimator, receiver and LiDAR report.

One step is one LiDAR revolution (0.1 s at 10 Hz) with the two thruster commands held. The
scenario file chooses world, stretch, sensors, faults, matchers and estimators; the agent sees the
output of one estimator (`estimator`, default the scenario's control.steer_on, else ekf), the
latest GPS fix as the receiver reports it, and a LiDAR range image of the real simulated scan. The
truth (pose, errors, clearance) is in `info`, never in the observation.

Observation (Dict):
- estimate: (along-track m from the stretch start, cross-track m (left +), heading error rad) of
  the estimator's pose relative to the route; estimate_cov its (x, y, yaw) covariance rotated to
  (along, cross, yaw); estimate_valid 0 until the estimator has a pose (then both are zeros).
- gps: (along m, cross m, HDOP, satellites used, age s) of the latest fix; gps_quality its GGA
  quality (0 no fix, 1 GPS, 2 SBAS/DGPS, 4 RTK fixed, 5 RTK float, 6 dead reckoning).
- lidar: (32, azimuth_bins) nearest range per beam (row 0 the highest) and azimuth bin (from
  behind, counter-clockwise through ahead), metres; 0 where nothing returned.

Reward per step (RewardConfig): progress_weight x metres gained along the route by the true
position, minus cross_track_weight x |true cross-track| m x step seconds, minus collision_penalty
on a collision. Terminated on a collision or at the end of the stretch; truncated at the time
limit (control.time_limit_factor x the stretch's planned time). `info["outcome"]` (completed,
collision, time_limit) is there only on the step that ends the episode.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import gymnasium
import numpy as np
from gymnasium import spaces
from pydantic import BaseModel, ConfigDict, Field

import worlds
from riverbench.angles import wrap_angle
from scenarios.gym import observation
from scenarios.pipeline.assembly import assemble, matcher_setups
from scenarios.pipeline.feed import Feed
from scenarios.pipeline.inertial import with_inertial
from scenarios.pipeline.matcher_pool import MatcherPool
from scenarios.pipeline.stream import FixEvent, ScanEvent
from scenarios.pipeline.vessel_run import VesselRun, autopilot_heading
from scenarios.spec.scenario import Scenario
from sim.autopilot import Autopilot
from sim.compass import Ahrs, with_heading
from sim.scan import POINT_DTYPE


class RewardConfig(BaseModel):
    """Weights of the reward (see the module docstring)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    progress_weight: float = Field(1.0, description="reward per metre gained along the route")
    cross_track_weight: float = Field(0.1, ge=0, description="penalty per metre of cross-track error per second")
    collision_penalty: float = Field(100.0, ge=0, description="penalty when the hull touches a structure")


@dataclass
class _Episode:
    """Everything one episode builds fresh (its seed's sensors, estimators, matchers and vessel)."""

    run: VesselRun
    pool: MatcherPool
    feed: Feed
    pilot: Autopilot
    compass: Ahrs
    last_fix: object = None
    last_scan: object = None
    station_m: float = 0.0
    sensed_until: float = 0.0
    """Stamp of the last scan or fix fed: the IMU and compass outputs up to it have been fed too."""


class RiverNavEnv(gymnasium.Env):
    """Gymnasium environment over a riverbench scenario (module docstring: spaces, reward, episode end)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self,
        scenario: str | os.PathLike | Scenario = "quickstart",
        estimator: str | None = None,
        azimuth_bins: int = 90,
        reward: RewardConfig | dict | None = None,
        render_mode: str | None = None,
        set: list[str] | tuple[str, ...] = (),
    ):
        import scenarios

        base = scenario if isinstance(scenario, Scenario) else scenarios.load(scenario, set=list(set))
        if render_mode not in (None, *self.metadata["render_modes"]):
            raise ValueError(f"render_mode {render_mode!r}: one of None, 'rgb_array'")
        ids = [e.id for e in base.estimators]
        if estimator is None:
            estimator = base.control.steer_on if base.control.steer_on in ids else ("ekf" if "ekf" in ids else (ids or [None])[0])
        if estimator not in ids:
            raise ValueError(f"estimator {estimator!r}: the scenario has {', '.join(ids) or 'no estimators'}")
        if not isinstance(azimuth_bins, int) or azimuth_bins < 1:
            raise ValueError(f"azimuth_bins must be a positive integer, got {azimuth_bins!r}")
        control = base.control.model_copy(update={"mode": "closed_loop", "steer_on": estimator})
        self.scenario = base.model_copy(update={"control": control})
        self.estimator, self.azimuth_bins, self.render_mode = estimator, azimuth_bins, render_mode
        self.reward_config = reward if isinstance(reward, RewardConfig) else RewardConfig(**(reward or {}))
        self.world = worlds.load(self.scenario.world, **self.scenario.world_params)
        self.max_range_m = self.scenario.lidar.max_range_m
        self.action_space = spaces.Box(-1.0, 1.0, (2,), np.float32)
        self.observation_space = observation.space(azimuth_bins, self.max_range_m)
        self._episode: _Episode | None = None
        self._renderer = None

    # ---- episode ---------------------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """A new episode; its sensors, waves and filters draw from `seed` (or one drawn from the env's generator)."""
        super().reset(seed=seed)
        self._close_episode()
        episode_seed = int(seed) if seed is not None else int(self.np_random.integers(0, 2**31 - 1))
        sc = self.scenario.model_copy(update={"seed": episode_seed})
        stack = assemble(sc, self.world)
        run, t_start = stack.vessel_run, stack.t_start
        pool = MatcherPool(matcher_setups(sc), workers=1)
        recorder = stack.recorder()
        feed = Feed(sc, pool.__enter__(), recorder, run.trajectory.pose, t_start)
        pilot = Autopilot(self.world.route, sc.control.dynamics, sc.vessel.speed_mps, sc.control.autopilot)
        compass = autopilot_heading(sc, self.world, run.compass)
        self._episode = _Episode(run, pool, feed, pilot, compass, sensed_until=float(run.loop.t))
        self._episode.station_m = run.loop.station_m
        self._start_station = self._episode.station_m
        return self._observe(), self._info()

    def step(self, action):
        ep = self._require_episode()
        act = np.asarray(action, dtype=np.float64).reshape(-1)
        if act.shape != (2,) or not np.isfinite(act).all():
            raise ValueError(f"action must be two finite thruster commands in [-1, 1], got {action!r}")
        loop = ep.run.loop
        events = loop.step(tuple(np.clip(act, -1.0, 1.0)))
        # the IMU's and compass's outputs between the step's scans and fixes, as a run feeds them (none without such sensors)
        for event in with_inertial(iter(events), ep.run.trajectory, ep.run.imu, ep.run.compass, ep.sensed_until):
            ep.feed.push(event)
            if isinstance(event, ScanEvent):
                ep.last_scan = event.scan
            elif isinstance(event, FixEvent):
                ep.last_fix = event.fix
        if events:
            ep.sensed_until = max(ep.sensed_until, float(events[-1].stamp))
        ep.feed.finish()
        log = ep.run.watch.log
        station = loop.station_m
        cfg = self.reward_config
        cross = abs(log.rows[-1][5])
        reward = cfg.progress_weight * (station - ep.station_m) - cfg.cross_track_weight * cross * ep.run.lidar.revolution_s
        ep.station_m = station
        if log.contact is not None:
            reward -= cfg.collision_penalty
        terminated = log.outcome in ("collision", "completed")
        truncated = log.outcome == "time_limit"
        info = self._info()
        if terminated or truncated:
            info["outcome"] = log.outcome  # only at the end: mid-episode the log's "interrupted" would be a false outcome
        return self._observe(), float(reward), terminated, truncated, info

    def baseline_action(self) -> np.ndarray:
        """What the bench's LOS autopilot would command now, steering on the observed estimator's position and the
        boat's compass (the reference policy; call once per step, it keeps its own filter state)."""
        ep = self._require_episode()
        t = ep.run.loop.t
        yaw, rate = ep.compass.read(ep.run.trajectory, t, ep.run.t_start)
        return np.array(ep.pilot.commands(t, with_heading(ep.feed.pose_of(self.estimator), yaw), rate), dtype=np.float32)

    def _observe(self) -> dict:
        ep = self._require_episode()
        est = ep.feed.estimators[self.estimator]
        alive = self.estimator not in ep.feed.dead
        pose = ep.feed.pose_of(self.estimator)
        cov = np.asarray(est.cov, dtype=float) if alive else np.full((3, 3), np.nan)
        route = self.world.route
        obs = observation.estimate(route, self._start_station, pose, cov)
        obs |= observation.gps(route, self._start_station, ep.last_fix, ep.run.loop.t)
        points = ep.last_scan.points if ep.last_scan is not None else np.zeros(0, dtype=POINT_DTYPE)
        obs["lidar"] = observation.range_image(points, self.azimuth_bins, self.max_range_m)
        return obs

    def _info(self) -> dict:
        """The truth, for analysis: never part of the observation."""
        ep = self._require_episode()
        t = ep.run.loop.t
        true_pose = ep.run.trajectory.pose(t)
        clearance = ep.run.watch.clearance.at(true_pose)[0]
        station, cross, heading = self.world.route.project(true_pose[:2, 3])
        yaw = math.atan2(true_pose[1, 0], true_pose[0, 0])
        estimate = ep.feed.pose_of(self.estimator)
        log = ep.run.watch.log
        info = {
            "t": t,
            "true_pose": true_pose,
            "true_station_m": float(station),
            "true_cross_track_m": float(cross),
            "true_heading_error_rad": wrap_angle(yaw - float(heading)),
            "clearance_m": clearance.distance_m,
            "nearest_part": self.world.parts[clearance.part].name if clearance.part >= 0 else "",
            "collision_part": log.contact.part if log.contact else "",
        }
        # errors only when there is something to compare (NaN would make equal episodes compare unequal)
        if np.isfinite(estimate).all():
            info["estimate_error_m"] = float(np.hypot(*(estimate[:2, 3] - true_pose[:2, 3])))
        if ep.last_fix is not None and ep.last_fix.quality:
            info["fix_error_m"] = float(np.hypot(*ep.last_fix.truth.error[:2]))
        return info

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        from scenarios.gym.render import TopView

        ep = self._require_episode()
        if self._renderer is None:
            self._renderer = TopView(self.world)
        return self._renderer.draw(ep.run.trajectory, ep.run.loop.t, ep.feed.pose_of(self.estimator), ep.last_fix, ep.last_scan, ep.run.watch.log)

    def close(self):
        self._close_episode()
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        super().close()

    def _close_episode(self) -> None:
        if self._episode is not None:
            self._episode.pool.__exit__(None, None, None)
            self._episode = None

    def _require_episode(self) -> _Episode:
        if self._episode is None:
            raise RuntimeError("RiverNav: call reset() before step() or render()")
        return self._episode
