"""A strapdown 3-axis gyro and accelerometer from named datasheets, sampled from the vessel's exact motion.

Each sample is  quantise(saturate(M (truth) + turn-on bias + Gauss-Markov bias + bias random walk + white noise))
per axis, M = I + scale-factor errors + axis misalignment, all drawn once per run from the
datasheet's tolerances. The noise terms are set so that the simulated sensor's Allan deviation
reads back the datasheet's noise density (at tau = 1 s) and bias instability (the floor / 0.664);
see sim.sensor_noise. `[imu]` in a scenario is ImuConfig: a preset (a named part) and overrides.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from riverbench.rng import stream
from riverbench.samples import ImuSamples
from riverbench.unixtime import on_ns_grid
from sim.kinematics import body_motion, earth_rate_enu, normal_gravity
from sim.sensor_noise import FLICKER_FLOOR, NoiseSpec, TriadNoise, gauss_markov_sigma

STANDARD_GRAVITY = 9.80665
"""m/s^2 per g, the unit datasheets give accelerometer figures in (CGPM 1901)."""
MAX_RATE_HZ = 400.0


class _TriadSpec(BaseModel):
    """What a gyroscope and an accelerometer triad share: the bias's correlation time and the errors drawn once per run."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    bias_correlation_s: float = Field(
        100.0, gt=0, description="correlation time of the Gauss-Markov bias that realises the bias instability, s (a model choice, see PRESETS)"
    )
    scale_factor: float = Field(0.0, ge=0, description="1-sigma scale-factor error drawn once per run per axis, fraction")
    misalignment_deg: float = Field(0.0, ge=0, description="1-sigma axis misalignment (cross-axis sensitivity) drawn once per run per pair, deg")


class GyroSpec(_TriadSpec):
    """Gyroscope triad error figures, in a datasheet's units."""

    noise_density_dps: float = Field(..., ge=0, description="rate noise density, deg/s/sqrt(Hz) (angle random walk x 60 in deg/sqrt(h))")
    bias_instability_dph: float = Field(..., ge=0, description="in-run bias stability (Allan floor / 0.664), deg/h; 0 when the datasheet gives none")
    bias_random_walk_dphrh: float = Field(0.0, ge=0, description="rate random walk, deg/h/sqrt(h) (a model choice, see PRESETS)")
    turn_on_bias_dps: float = Field(0.0, ge=0, description="1-sigma bias drawn once per run (zero-rate offset), deg/s")
    range_dps: float = Field(..., gt=0, description="full-scale range, deg/s: outputs saturate there")
    resolution_dps: float = Field(0.0, ge=0, description="output quantisation step (LSB), deg/s; 0 for floating-point output")


class AccelSpec(_TriadSpec):
    """Accelerometer triad error figures, in a datasheet's units."""

    noise_density_ug: float = Field(..., ge=0, description="noise density, micro-g/sqrt(Hz) (velocity random walk)")
    bias_instability_ug: float = Field(..., ge=0, description="in-run bias stability (Allan floor / 0.664), micro-g; 0 when the datasheet gives none")
    bias_random_walk_ugrs: float = Field(0.0, ge=0, description="acceleration random walk, micro-g/sqrt(s) (a model choice, see PRESETS)")
    turn_on_bias_mg: float = Field(0.0, ge=0, description="1-sigma bias drawn once per run (zero-g offset), milli-g")
    range_g: float = Field(..., gt=0, description="full-scale range, g: outputs saturate there")
    resolution_ug: float = Field(0.0, ge=0, description="output quantisation step (LSB), micro-g; 0 for floating-point output")


PARTS = ("bmi088", "mti630")
"""The presets, in the columns of DATASHEETS."""

DATASHEETS: tuple[tuple[str, float, float, str], ...] = (
    # (sensor.field, BMI088, MTi-630, source). BMI088: Bosch Sensortec BMI088 data sheet BST-BMI088-DS001 (rev. 1.3, May
    # 2018; 1.4, Sep 2018), Table 1 (accelerometer) and 2 (gyroscope), typical values, which Bosch states as 1 sigma.
    # MTi-630: Xsens (Movella) MTi 600-series datasheet MT1603P (2020.B), sensor specifications; the unit outputs
    # calibrated floating-point data, its turn-on bias, scale and alignment calibrated out to the residuals given.
    ("gyro.noise_density_dps", 0.014, 0.007, "output noise density, deg/s/sqrt(Hz)"),
    ("gyro.bias_instability_dph", 2.0, 8.0, "in-run bias stability, deg/h"),
    ("gyro.turn_on_bias_dps", 1.0, 0.0, "BMI088 zero-rate offset +-1 deg/s typ.; MTi: calibrated"),
    ("gyro.scale_factor", 0.01, 0.001, "BMI088 sensitivity tolerance +-1 %; MTi 0.1 % residual (its non-linearity 0.1 % FS)"),
    ("gyro.misalignment_deg", 0.57, 0.05, "BMI088 cross-axis sensitivity +-1 % = asin(0.01); MTi 0.05 deg residual alignment"),
    ("gyro.range_dps", 500.0, 2000.0, "BMI088 range register set to +-500 deg/s; MTi +-2000 deg/s standard full range"),
    ("gyro.resolution_dps", 1.0 / 65.536, 0.0, "BMI088 65.536 LSB/(deg/s) at +-500 deg/s (16 bit); MTi floating point"),
    ("accel.noise_density_ug", 175.0, 60.0, "noise density, micro-g/sqrt(Hz)"),
    ("accel.bias_instability_ug", 0.0, 10.0, "in-run bias stability, micro-g (the BMI088's data sheet gives none)"),
    ("accel.turn_on_bias_mg", 20.0, 0.0, "BMI088 zero-g offset +-20 mg typ.; MTi: calibrated"),
    ("accel.scale_factor", 0.01, 0.001, "BMI088 sensitivity tolerance +-1 %; MTi 0.1 % residual"),
    ("accel.misalignment_deg", 0.57, 0.05, "BMI088 cross-axis sensitivity +-1 %; MTi 0.05 deg residual alignment"),
    ("accel.range_g", 6.0, 10.0, "BMI088 range register set to +-6 g; MTi +-10 g standard full range"),
    ("accel.resolution_ug", 1e6 / 5460.0, 0.0, "BMI088 5460 LSB/g at +-6 g (16 bit); MTi floating point"),
)
"""One table of every preset's datasheet figures: a row per field, a column per part (PARTS), and the row's source."""


def _noise_placement(density: float, instability: float) -> tuple[float, float]:
    """(bias correlation time s, random-walk density) that give the Allan deviation a flat floor at the datasheet's bias
    instability, in the units of `density` (per sqrt(Hz)) and `instability`, with the walk per sqrt(s).

    Neither is on a datasheet; every preset places them by one rule: with r = (N / (0.664 B))^2 the time where white
    noise alone falls to the floor, T = 2 r and K = sqrt(0.15) (0.664 B)^2 / N (the random walk reaches the floor at
    20 r). The floor then lies between about r and 10 r: ~20-300 s for the MTi-630 gyro, ~1,500-15,000 s for the BMI088's."""
    floor = FLICKER_FLOOR * instability
    return 2.0 * (density / floor) ** 2, math.sqrt(0.15) * floor**2 / density


def _presets() -> dict[str, dict[str, dict[str, float]]]:
    """DATASHEETS as {part: {"gyro": {...}, "accel": {...}}}, with each bias's correlation time and random walk placed."""
    out: dict[str, dict[str, dict[str, float]]] = {part: {"gyro": {}, "accel": {}} for part in PARTS}
    for key, *values, _source in DATASHEETS:
        sensor, field = key.split(".")
        for part, value in zip(PARTS, values):
            out[part][sensor][field] = value
    for figures in out.values():
        g, a = figures["gyro"], figures["accel"]
        if g["bias_instability_dph"] > 0:  # deg/s/sqrt(Hz) -> deg/h/sqrt(Hz); the walk deg/h/sqrt(s) -> deg/h/sqrt(h)
            g["bias_correlation_s"], walk = _noise_placement(3600.0 * g["noise_density_dps"], g["bias_instability_dph"])
            g["bias_random_walk_dphrh"] = 60.0 * walk
        if a["bias_instability_ug"] > 0:
            a["bias_correlation_s"], a["bias_random_walk_ugrs"] = _noise_placement(a["noise_density_ug"], a["bias_instability_ug"])
    return out


PRESETS: dict[str, dict[str, dict[str, float]]] = _presets()
"""{part: {"gyro": GyroSpec fields, "accel": AccelSpec fields}} from DATASHEETS."""


class ImuConfig(BaseModel):
    """The boat's IMU: a named datasheet part (`preset`) whose figures any field below overrides."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    preset: Literal["mti630", "bmi088"] = Field(
        "mti630", description="the part: mti630 (Xsens MTi-630 industrial AHRS) or bmi088 (Bosch BMI088 consumer MEMS)"
    )
    rate_hz: float = Field(
        100.0, gt=0, le=MAX_RATE_HZ, description="output data rate, Hz (at most 400); a whole number of samples per LiDAR revolution"
    )
    gyro: GyroSpec = Field(default_factory=lambda: GyroSpec(**PRESETS["mti630"]["gyro"]), description="gyroscope figures (default: the preset's)")
    accel: AccelSpec = Field(
        default_factory=lambda: AccelSpec(**PRESETS["mti630"]["accel"]), description="accelerometer figures (default: the preset's)"
    )
    lever_m: tuple[float, float, float] = Field((0.0, 0.0, 0.0), description="IMU position on base_link, m (x fwd, y left, z up)")
    earth_rate: bool = Field(True, description="the gyro senses the Earth's rotation (7.29e-5 rad/s; 10 deg/h about the vertical at 42 deg N)")

    @model_validator(mode="before")
    @classmethod
    def _preset(cls, data):
        """Fill gyro and accel from the preset; given fields override the preset's one by one."""
        if not isinstance(data, dict):
            return data
        preset = data.get("preset", "mti630")
        if preset not in PRESETS:
            return data  # the Literal names the problem
        out = dict(data)
        for key in ("gyro", "accel"):
            given = data.get(key, {})
            if isinstance(given, BaseModel):
                given = given.model_dump()
            out[key] = {**PRESETS[preset][key], **given} if isinstance(given, dict) else given
        return out

    @model_validator(mode="after")
    def _realisable(self) -> ImuConfig:
        """The bias instability must lie above what white noise and the random walk alone give (else no GM bias can realise it)."""
        self.noise_specs()
        return self

    def noise_specs(self) -> tuple[NoiseSpec, NoiseSpec]:
        """(gyro, accel) stochastic models in SI units (rad/s, m/s^2 based)."""
        g, a = self.gyro, self.accel
        out = []
        for key, white, instability, tau, walk in (
            (
                "gyro",
                math.radians(g.noise_density_dps),
                math.radians(g.bias_instability_dph) / 3600.0,
                g.bias_correlation_s,
                math.radians(g.bias_random_walk_dphrh) / 3600.0 / 60.0,
            ),
            (
                "accel",
                a.noise_density_ug * 1e-6 * STANDARD_GRAVITY,
                a.bias_instability_ug * 1e-6 * STANDARD_GRAVITY,
                a.bias_correlation_s,
                a.bias_random_walk_ugrs * 1e-6 * STANDARD_GRAVITY,
            ),
        ):
            try:
                sigma = gauss_markov_sigma(white, instability, tau, walk)
            except ValueError as exc:
                raise ValueError(f"{key}.bias_instability: {exc}") from None
            out.append(NoiseSpec(white, sigma, tau, walk))
        return out[0], out[1]


def samples_per_period(rate_hz: float, period_s: float) -> int:
    """How many IMU samples fit in one simulation period; a ValueError naming imu.rate_hz when not a whole number."""
    n = rate_hz * period_s
    if abs(n - round(n)) > 1e-6 or round(n) < 1:
        raise ValueError(
            f"imu.rate_hz: {rate_hz:g} Hz gives {n:g} samples per {period_s:g} s period; a whole number is needed (a multiple of {1 / period_s:g} Hz)"
        )
    return int(round(n))


class Imu:
    """`sample(trajectory, ts)` -> ImuSamples at increasing times ts (the biases carry over between calls).

    origin_lat_deg sets gravity and the Earth's rate; seed the random draws (turn-on errors and noise).
    """

    def __init__(self, config: ImuConfig | None = None, seed: int = 0, origin_lat_deg: float = 42.3539):
        self.config = config or ImuConfig()
        cfg = self.config
        rng = stream(seed, "sim.imu")
        self.period = 1.0 / cfg.rate_hz
        gyro_spec, accel_spec = cfg.noise_specs()
        # one stream per noise source, so that a record comes out the same whatever batches it is drawn in
        self._gyro_noise = TriadNoise(gyro_spec, self.period, stream(seed, "sim.imu.gyro"))
        self._accel_noise = TriadNoise(accel_spec, self.period, stream(seed, "sim.imu.accel"))
        g, a = cfg.gyro, cfg.accel
        self._gyro_bias = math.radians(g.turn_on_bias_dps) * rng.standard_normal(3)
        self._accel_bias = a.turn_on_bias_mg * 1e-3 * STANDARD_GRAVITY * rng.standard_normal(3)
        self._gyro_m = _error_matrix(g.scale_factor, math.radians(g.misalignment_deg), rng)
        self._accel_m = _error_matrix(a.scale_factor, math.radians(a.misalignment_deg), rng)
        self.gravity = normal_gravity(origin_lat_deg)
        self._earth = earth_rate_enu(origin_lat_deg) if cfg.earth_rate else np.zeros(3)
        self._lever = np.asarray(cfg.lever_m, dtype=float)
        self.gyro_range, self.gyro_lsb = math.radians(g.range_dps), math.radians(g.resolution_dps)
        self.accel_range, self.accel_lsb = a.range_g * STANDARD_GRAVITY, a.resolution_ug * 1e-6 * STANDARD_GRAVITY
        self._last = -math.inf

    @property
    def gyro_noise_density(self) -> float:
        """White noise density, rad/s/sqrt(Hz)."""
        return self._gyro_noise.spec.white

    @property
    def accel_noise_density(self) -> float:
        """White noise density, m/s^2/sqrt(Hz)."""
        return self._accel_noise.spec.white

    def times(self, t0: float, t1: float) -> np.ndarray:
        """Sample times k / rate_hz in (t0, t1] (the grid every run shares, so batches never overlap nor leave gaps), on
        the nanosecond grid as a bag stamps them: k * period is 1 ulp above k / rate_hz for 14% of k at 100 Hz, which put
        a batch's stamp after the compass heading of the same instant, and the filter refused the heading as out of order."""
        k0 = math.floor(t0 * self.config.rate_hz + 1e-9) + 1
        k1 = math.floor(t1 * self.config.rate_hz + 1e-9)
        return on_ns_grid(np.arange(k0, k1 + 1) / self.config.rate_hz)

    def sample(self, trajectory, ts: np.ndarray) -> ImuSamples:
        """The sensor's outputs at times ts (increasing, after every earlier call's): truth from the trajectory plus the errors."""
        ts = np.atleast_1d(np.asarray(ts, dtype=float))
        if len(ts) and (ts[0] <= self._last or np.any(np.diff(ts) <= 0)):
            raise ValueError(f"imu: sample times must increase (got {ts[0]:.4f} after {self._last:.4f})")
        n = len(ts)
        if n == 0:
            return ImuSamples(ts, np.zeros((0, 3)), np.zeros((0, 3)), self.gyro_noise_density, self.accel_noise_density)
        self._last = float(ts[-1])
        motion = body_motion(trajectory, ts, self.gravity, self._earth, self._lever)
        gyro = motion.omega @ self._gyro_m.T + self._gyro_bias + self._gyro_noise.draw(n)
        accel = motion.specific_force @ self._accel_m.T + self._accel_bias + self._accel_noise.draw(n)
        return ImuSamples(
            ts,
            _digitise(gyro, self.gyro_range, self.gyro_lsb),
            _digitise(accel, self.accel_range, self.accel_lsb),
            self.gyro_noise_density,
            self.accel_noise_density,
        )


def _error_matrix(scale_sigma: float, misalign_sigma: float, rng: np.random.Generator) -> np.ndarray:
    """I + diag(scale errors) + off-diagonal misalignments (small angles), drawn once."""
    draw = rng.standard_normal((3, 3))
    m = np.eye(3) + misalign_sigma * draw
    m[np.diag_indices(3)] = 1.0 + scale_sigma * np.diag(draw)
    return m


def _digitise(values: np.ndarray, full_scale: float, lsb: float) -> np.ndarray:
    """Saturate at +-full_scale and round to the LSB (lsb 0: no quantisation)."""
    out = np.clip(values, -full_scale, full_scale)
    return np.round(out / lsb) * lsb if lsb > 0 else out
