"""Exact vessel motion along a world's route: speed profile, heading, wave roll/pitch/heave."""

from __future__ import annotations

from functools import cached_property

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field, model_validator
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

from riverbench.rng import stream
from sim.plane_motion import PlaneMotion
from sim.vessel import HullConfig, hull_mesh
from sim.waves import WaveMotion, WindWaves
from worlds.world import World


class TrajectoryConfig(BaseModel):
    """Motion parameters; every distance in metres, angles in degrees, times in seconds."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    speed_mps: float = Field(2.0, gt=0, le=10, description="mean speed over ground")
    speed_variation: float = Field(0.2, ge=0, lt=1, description="relative amplitude of the slow speed oscillation (0.2: 1.6-2.4 m/s at 2 m/s)")
    speed_period_s: float = Field(90.0, gt=0, description="period of the speed oscillation")
    sea_state: int = Field(0, ge=0, le=4, description="Douglas sea state; 0 is calm (no wave motion)")
    wind_waves: WindWaves | None = Field(
        None,
        description="a fetch-limited wind sea instead of a sea state: {wind_mps, fetch_m} (sim.waves.WindWaves, the Coastal "
        "Engineering Manual's growth laws) [None: the sea state's]",
    )
    start_m: float = Field(0.0, ge=0, description="route station where the run starts")
    end_m: float | None = Field(None, gt=0, description="route station where the run ends (default: route end)")
    lateral_offset_m: float = Field(0.0, description="constant offset to the left of the route centreline")
    mount_xyz: tuple[float, float, float] = Field((0.0, 0.0, 1.8), description="LiDAR origin on base_link (x fwd, y left, z up from the waterline)")
    mount_rpy_deg: tuple[float, float, float] = Field((0.0, 0.0, 0.0), description="LiDAR roll, pitch, yaw on base_link (0: forward-facing, level)")
    hull: HullConfig = Field(default_factory=HullConfig, description="vessel body that occludes the LiDAR")
    seed: int = Field(0, description="seed of the speed-profile phase and the wave components")

    @model_validator(mode="after")
    def _one_sea(self) -> TrajectoryConfig:
        if self.wind_waves is not None and self.sea_state != 0:
            raise ValueError(f"give sea_state ({self.sea_state}) or wind_waves, not both: each sets the waves")
        return self

    def wave_motion(self, rng: np.random.Generator) -> WaveMotion:
        """The vessel's wave motion, its components drawn from rng: the wind sea's if given, else the sea state's."""
        beam, length = self.hull.beam_m, self.hull.length_m
        if self.wind_waves is not None:
            return WaveMotion.from_wind(self.wind_waves, rng, beam_m=beam, length_m=length)
        return WaveMotion.from_sea_state(self.sea_state, rng, beam_m=beam, length_m=length)


class VesselPoses:
    """What the sensors ask of a vessel's motion, built on the subclass's `poses(ts)`, `config` (TrajectoryConfig)
    and `mount`: single poses, the LiDAR's poses and the hull that occludes it."""

    config: TrajectoryConfig
    mount: np.ndarray

    def poses(self, ts: np.ndarray) -> np.ndarray:
        """(N, 4, 4) world<-base_link at times ts (N,): the subclass's motion."""
        raise NotImplementedError

    @cached_property
    def hull(self) -> trimesh.Trimesh:
        """The vessel body in base_link, up to the LiDAR mount (what the sensor cannot see through)."""
        return hull_mesh(self.config.hull, mast_top_m=self.config.mount_xyz[2] - 0.1)

    def pose(self, t: float) -> np.ndarray:
        """4x4 world<-base_link at time t."""
        return self.poses(np.array([t]))[0]

    def lidar_poses(self, ts: np.ndarray) -> np.ndarray:
        """(N, 4, 4) world<-lidar at times ts."""
        return self.poses(ts) @ self.mount

    def lidar_pose(self, t: float) -> np.ndarray:
        """4x4 world<-lidar at time t."""
        return self.lidar_poses(np.array([t]))[0]


def wave_poses(ts: np.ndarray, xy: np.ndarray, yaw: np.ndarray, waves: WaveMotion) -> np.ndarray:
    """(N, 4, 4) world<-base_link from the plane motion (xy (N, 2), yaw) and the waves' heave, roll and pitch at ts."""
    heave, roll, pitch = waves.at(ts)
    out = np.zeros((len(ts), 4, 4))
    out[:, :3, :3] = yaw_pitch_roll_matrices(yaw, pitch, roll)
    out[:, :2, 3] = xy
    out[:, 2, 3] = heave
    out[:, 3, 3] = 1.0
    return out


class Trajectory(VesselPoses):
    """The vessel's true motion: `pose(t)` is world<-base_link, exact at any t in [0, duration]."""

    def __init__(self, world: World, speed_mps: float = 2.0, sea_state: int = 0, start_m: float = 0.0, **more):
        self.config = TrajectoryConfig(speed_mps=speed_mps, sea_state=sea_state, start_m=start_m, **more)
        self.route = world.route
        cfg = self.config
        self.end_m = self.route.length if cfg.end_m is None else cfg.end_m
        if not cfg.start_m < self.end_m <= self.route.length + 1e-9:
            raise ValueError(
                f"trajectory: need start_m < end_m <= route length {self.route.length:.1f} m, got start_m={cfg.start_m}, end_m={self.end_m}"
            )
        rng = stream(cfg.seed, "sim.trajectory")
        self._speed_phase = float(rng.uniform(0.0, 2.0 * np.pi))
        self.waves = cfg.wave_motion(rng)
        self.duration = float(brentq(lambda t: self.station(t) - self.end_m, 0.0, 10 * self.end_m / cfg.speed_mps))
        self.mount = mount_matrix(cfg)

    def station(self, t: float | np.ndarray) -> np.ndarray:
        """Route arc length (m) reached at time t: the integral of the oscillating speed profile."""
        cfg = self.config
        w = 2.0 * np.pi / cfg.speed_period_s
        t = np.asarray(t, dtype=float)
        wobble = (np.cos(self._speed_phase) - np.cos(w * t + self._speed_phase)) / w
        return cfg.start_m + cfg.speed_mps * (t + cfg.speed_variation * wobble)

    def speed(self, t: float | np.ndarray) -> np.ndarray:
        """Speed over ground (m/s) at time t."""
        cfg = self.config
        w = 2.0 * np.pi / cfg.speed_period_s
        return cfg.speed_mps * (1.0 + cfg.speed_variation * np.sin(w * np.asarray(t, dtype=float) + self._speed_phase))

    def plane_motion(self, ts: np.ndarray) -> PlaneMotion:
        """Position, yaw and their exact time derivatives at ts: the speed profile's and the route's (heading linear
        between route vertices, so the curvature is the heading's slope there) differentiated analytically."""
        ts = np.atleast_1d(np.asarray(ts, dtype=float))
        self._check_times(ts)
        cfg = self.config
        station = self.station(ts)
        xy, yaw = self.route.at(station)
        s = self.route.s
        i = np.clip(np.searchsorted(s, station, side="right") - 1, 0, len(s) - 2)
        inside = (station >= 0.0) & (station <= self.route.length)
        curvature = np.where(inside, (self.route.heading[i + 1] - self.route.heading[i]) / (s[i + 1] - s[i]), 0.0)
        w = 2.0 * np.pi / cfg.speed_period_s
        speed = np.where(inside, self.speed(ts), 0.0)
        speed_dot = np.where(inside, cfg.speed_mps * cfg.speed_variation * w * np.cos(w * ts + self._speed_phase), 0.0)
        tangent = np.stack([np.cos(yaw), np.sin(yaw)], axis=-1)
        normal = np.stack([-np.sin(yaw), np.cos(yaw)], axis=-1)
        scale = 1.0 - cfg.lateral_offset_m * curvature  # an offset path is longer outside a bend, shorter inside
        if cfg.lateral_offset_m:
            xy = xy + cfg.lateral_offset_m * normal
        velocity = (speed * scale)[:, None] * tangent
        acceleration = (speed_dot * scale)[:, None] * tangent + (speed**2 * scale * curvature)[:, None] * normal
        return PlaneMotion(xy, yaw, velocity, acceleration, curvature * speed)

    def poses(self, ts: np.ndarray) -> np.ndarray:
        """(N, 4, 4) world<-base_link at times ts (N,), vectorised."""
        ts = np.atleast_1d(np.asarray(ts, dtype=float))
        self._check_times(ts)
        xy, yaw = self.route.at(self.station(ts))
        if self.config.lateral_offset_m:
            xy = xy + self.config.lateral_offset_m * np.stack([-np.sin(yaw), np.cos(yaw)], axis=-1)
        return wave_poses(ts, xy, yaw, self.waves)

    def _check_times(self, ts: np.ndarray) -> None:
        if not np.isfinite(ts).all():
            raise ValueError("trajectory: time is NaN or infinite")
        if ts.min() < 0.0 or ts.max() > self.duration + 1.0:
            raise ValueError(f"trajectory: time {ts.min():.3f}..{ts.max():.3f} s outside the run 0..{self.duration:.1f} s")


def mount_matrix(config: TrajectoryConfig) -> np.ndarray:
    """4x4 base_link<-lidar from the configured mount position and roll, pitch, yaw."""
    mount = np.eye(4)
    mount[:3, :3] = Rotation.from_euler("xyz", config.mount_rpy_deg, degrees=True).as_matrix()
    mount[:3, 3] = config.mount_xyz
    return mount


def yaw_pitch_roll_matrices(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """(N, 3, 3) Rz(yaw) Ry(pitch) Rx(roll), the intrinsic ZYX convention of REP-103.

    Written out because scipy's Rotation.from_euler costs ~1 us per angle triple, which is a
    third of the LiDAR's per-revolution budget; tests check it equals scipy's result.
    """
    cy, sy = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    return np.stack(
        [
            np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], axis=-1),
            np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], axis=-1),
            np.stack([-sp, cp * sr, cp * cr], axis=-1),
        ],
        axis=-2,
    )
