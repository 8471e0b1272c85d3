"""The boat's magnetic compass: a 3-axis magnetometer with hard- and soft-iron errors, tilt-compensated into a heading.

The field at the sensor is the Earth's (a fixed model value for the world's origin) plus that of the
steel the Earth's field magnetises (sim.magnetism), so a compass trusted under a steel bridge or beside
a lock gate errs. The magnetometer measures S b + h + noise, b the true field in base_link, S the
residual soft-iron matrix and h the residual hard-iron offset left after the boat's calibration (drawn
once per run); the unit levels that with its own roll and pitch estimate (the truth plus the AHRS's
tilt error) and turns it into a true heading with the model declination. `[compass]` in a scenario is
CompassConfig. This is the estimators' compass; the autopilot's heading sensor (sim.compass) is another unit of this model.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from riverbench.rng import stream
from riverbench.samples import HeadingSample
from riverbench.unixtime import on_ns_grid
from sim.magnetism import MOMENT_PER_TONNE, SteelField, earth_field_enu, steel_field

# IGRF-14 (Alken et al., Earth Planets Space, 2025) at the worlds' origin 42.3539 N, 71.1106 W, 0 m, epoch 2025.0
# (evaluated with ppigrf 2.1.0): D = -14.04 deg, I = 66.35 deg, F = 51,321 nT (E -4,995, N 19,968, U -47,012 nT).
# NOAA's WMM gives Boston's declination as about 14 deg W as well.
ORIGIN_DECLINATION_DEG = -14.04
ORIGIN_INCLINATION_DEG = 66.35
ORIGIN_INTENSITY_UT = 51.32


class CompassConfig(BaseModel):
    """Magnetometer, local field and steel disturbance. Defaults: an industrial AHRS's magnetometer (Xsens MTi
    family: +-8 G range, 0.5 mG RMS noise, 0.2 deg roll/pitch and 1 deg heading RMS, Movella MTi-300 leaflet, May 2023)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    rate_hz: float = Field(10.0, gt=0, le=100.0, description="heading output rate, Hz; a whole number of outputs per LiDAR revolution")
    noise_ut: float = Field(0.05, ge=0, description="magnetometer white noise per axis, microtesla (0.5 mG RMS, Movella MTi-300 leaflet)")
    hard_iron_ut: float = Field(
        0.2,
        ge=0,
        description="1-sigma residual hard-iron offset per axis after the boat's calibration, microtesla, drawn once per run "
        "(0.2 uT is ~0.6 deg of heading at Boston's 20.6 uT horizontal field, within the MTi's 1 deg RMS heading)",
    )
    soft_iron: float = Field(
        0.005, ge=0, description="1-sigma residual soft-iron error (scale and cross terms of S - I) after calibration, drawn once per run"
    )
    tilt_sigma_deg: float = Field(0.2, ge=0, description="the unit's roll/pitch error used to level the field, deg (MTi: 0.2 deg RMS)")
    heading_sigma_deg: float = Field(1.0, gt=0, description="heading accuracy the unit states with each output, deg (MTi: 1 deg RMS)")
    declination_deg: float = Field(
        ORIGIN_DECLINATION_DEG, ge=-180, le=180, description="magnetic declination at the world's origin, east positive (IGRF-14, Boston, 2025.0)"
    )
    inclination_deg: float = Field(ORIGIN_INCLINATION_DEG, ge=-90, le=90, description="inclination (dip), down positive (IGRF-14, Boston, 2025.0)")
    intensity_ut: float = Field(ORIGIN_INTENSITY_UT, gt=0, description="total field intensity, microtesla (IGRF-14, Boston, 2025.0)")
    steel: bool = Field(True, description="the world's steel structures disturb the field (sim.magnetism)")
    moment_per_tonne_am2: float = Field(
        MOMENT_PER_TONNE,
        ge=0,
        description="induced dipole moment per tonne of steel, A m^2 (270: 1 nT at 30 m per tonne, Breiner's rule of thumb)",
    )
    remanent_factor: float = Field(
        0.0,
        ge=0,
        description="permanent magnetisation of each steel part as a multiple of its induced moment, in a direction drawn per part "
        "(Breiner: it can add a factor of 3-5) [0: induced only]",
    )
    lever_m: tuple[float, float, float] = Field((0.0, 0.0, 1.0), description="magnetometer position on base_link, m (above the tray)")


class MagneticCompass:
    """`read(trajectory, ts)` -> HeadingSamples at times ts, from the world's field at the sensor."""

    def __init__(self, world, config: CompassConfig | None = None, seed: int = 0, steel: SteelField | None = None):
        """`steel`: the steel's dipoles if already known (e.g. a test's), else computed from the world when config.steel."""
        self.config = cfg = config or CompassConfig()
        self.earth = earth_field_enu(cfg.declination_deg, cfg.inclination_deg, cfg.intensity_ut)
        if steel is None:
            direction = self.earth / np.linalg.norm(self.earth)
            steel = steel_field(world, direction, cfg.moment_per_tonne_am2) if cfg.steel and world is not None else None
            if steel is not None and cfg.remanent_factor > 0:
                steel = _with_remanence(world, steel, cfg.remanent_factor, stream(seed, "sim.magnetic_compass.remanence"))
        self.steel = steel
        rng = stream(seed, "sim.magnetic_compass")
        self._hard = cfg.hard_iron_ut * rng.standard_normal(3)
        self._soft = np.eye(3) + cfg.soft_iron * rng.standard_normal((3, 3))
        self._noise = stream(seed, "sim.magnetic_compass.noise")
        self._lever = np.asarray(cfg.lever_m, dtype=float)

    @property
    def period(self) -> float:
        return 1.0 / self.config.rate_hz

    def times(self, t0: float, t1: float) -> np.ndarray:
        """Output times k / rate_hz in (t0, t1], on the nanosecond grid as a bag stamps them (and the IMU's samples are)."""
        rate = self.config.rate_hz
        return on_ns_grid(np.arange(math.floor(t0 * rate + 1e-9) + 1, math.floor(t1 * rate + 1e-9) + 1) / rate)

    def field_enu(self, points: np.ndarray) -> np.ndarray:
        """The true field (N, 3) at ENU points, microtesla: the Earth's plus the steel's."""
        points = np.atleast_2d(points)
        out = np.tile(self.earth, (len(points), 1))
        return out + self.steel.field_ut(points) if self.steel is not None else out

    def read(self, trajectory, ts: np.ndarray) -> list[HeadingSample]:
        """The unit's outputs at times ts."""
        ts = np.atleast_1d(np.asarray(ts, dtype=float))
        if not len(ts):
            return []
        cfg = self.config
        poses = trajectory.poses(ts)
        rot = poses[:, :3, :3]
        sensor = poses[:, :3, 3] + rot @ self._lever
        body = np.einsum("nji,nj->ni", rot, self.field_enu(sensor))
        measured = body @ self._soft.T + self._hard + cfg.noise_ut * self._noise.standard_normal((len(ts), 3))
        roll = np.arctan2(rot[:, 2, 1], rot[:, 2, 2]) + math.radians(cfg.tilt_sigma_deg) * self._noise.standard_normal(len(ts))
        pitch = -np.arcsin(np.clip(rot[:, 2, 0], -1.0, 1.0)) + math.radians(cfg.tilt_sigma_deg) * self._noise.standard_normal(len(ts))
        level = levelled(measured, roll, pitch)
        north_in_body = np.arctan2(level[:, 1], level[:, 0])
        yaw = math.radians(90.0 - cfg.declination_deg) - north_in_body
        yaw = (yaw + math.pi) % (2.0 * math.pi) - math.pi
        dip = dip_deg(level)
        sigma = math.radians(cfg.heading_sigma_deg)
        return [
            HeadingSample(float(t), float(y), m.copy(), sigma, float(d), float(r), float(p))
            for t, y, m, d, r, p in zip(ts, yaw, measured, dip, roll, pitch)
        ]


def dip_deg(level: np.ndarray) -> np.ndarray:
    """Dip (inclination, down positive) of levelled field vectors, deg: what a filter compares with the Earth's to spot steel."""
    return np.degrees(np.arctan2(-level[:, 2], np.hypot(level[:, 0], level[:, 1])))


def levelled(field: np.ndarray, roll: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """Body-frame vectors rotated into the level (yaw-only) frame: Ry(pitch) Rx(roll) v."""
    cr, sr, cp, sp = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch)
    x, y, z = field[:, 0], field[:, 1], field[:, 2]
    y1, z1 = cr * y - sr * z, sr * y + cr * z
    return np.stack([cp * x + sp * z1, y1, -sp * x + cp * z1], axis=-1)


def _with_remanence(world, steel: SteelField, factor: float, rng: np.random.Generator) -> SteelField:
    """Each steel part's cells get a permanent moment `factor` x their induced one's size, in one random direction per part."""
    moments = steel.moments.copy()
    size = np.linalg.norm(steel.moments, axis=1)
    parts = [p for p in world.parts if p.material.name == "steel"]
    if parts:
        centres = np.array([np.asarray(p.mesh.bounds).mean(axis=0) for p in parts])
        owner = np.argmin(np.linalg.norm(steel.positions[:, None, :] - centres[None], axis=-1), axis=1)
        directions = rng.standard_normal((len(parts), 3))
        directions /= np.linalg.norm(directions, axis=1, keepdims=True)
        moments += factor * size[:, None] * directions[owner]
    return SteelField(steel.positions, moments, steel.masses, steel.cell_m, steel.cutoff_m)
