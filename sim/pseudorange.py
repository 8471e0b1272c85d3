"""Pseudorange errors: a receiver clock, slowly varying and white per-satellite errors, C/N0.

A consumer receiver's code error has two parts: a slowly varying one (ionosphere and troposphere
residuals after the broadcast models, orbit and clock errors) that a position filter cannot
average out, and white noise from thermal noise and residual multipath. Both grow towards the
horizon with the obliquity mapping 1/sin(el). The slow part is a first-order Gauss-Markov process
per satellite; the defaults give an open-sky horizontal CEP50 of about 2.5 m (benchmarks/gnss.py).
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

SPEED_OF_LIGHT = 299_792_458.0
CLOCK_OFFSET_S = 1e-3
"""The receiver clock starts up to this far off GPS time (uniform), as a free-running TCXO."""
CLOCK_DRIFT_SIGMA = 1e-7
"""Standard deviation of the receiver clock's frequency error (0.1 ppm, dimensionless)."""


class PseudorangeNoise(BaseModel):
    """Elevation-dependent pseudorange error model; sigma(el) = zenith sigma / sin(el)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    white_zenith_m: float = Field(0.6, ge=0.0, description="Zenith sigma of white code noise per epoch, m.")
    correlated_zenith_m: float = Field(1.5, ge=0.0, description="Zenith sigma of the slowly varying (Gauss-Markov) error per satellite, m.")
    correlation_time_s: float = Field(300.0, gt=0.0, description="Correlation time of the slowly varying error, s.")
    cn0_zenith_dbhz: float = Field(48.0, description="Carrier-to-noise density of a direct signal at zenith, dB-Hz.")
    cn0_horizon_dbhz: float = Field(36.0, description="C/N0 of a direct signal at the horizon, dB-Hz (linear in sin(el)).")
    cn0_jitter_db: float = Field(1.0, ge=0.0, description="Sigma of the epoch-to-epoch C/N0 fluctuation, dB.")
    tracking_threshold_dbhz: float = Field(28.0, description="Signals below this C/N0 are not tracked, dB-Hz.")
    restart_white_zenith_m: float | None = Field(
        None,
        gt=0.0,
        description="Carrier smoothing restarts on loss of lock: a satellite tracked again after a gap has this zenith "
        "sigma of white code noise (the raw code's) on its first epoch; the smoothing filter's window then grows by an "
        "epoch at a time and averages the raw noise down as 1/sqrt(epochs since lock) towards white_zenith_m (the "
        "smoothed code's), its residual drifting from epoch to epoch (SmoothingLock), m. Receivers reset their "
        "code-carrier smoothing at reacquisition (Ashtech G12 reference manual, SMI: 'smoothing constant is changed "
        "from 1 to 1/SMI from locking a satellite ... After reacquisition, smoothing is reset'; NovAtel MiLLennium "
        "CSMOOTH: the lock time restarts and the smoothing takes its full effect only after the smoothing time; "
        "Septentrio PolaRx5 setSmoothingInterval: the noise 'will decrease over time'; Hemisphere, the V102's maker, "
        "smooths over 15 minutes by default, $JSMOOTH), and weight such a range by its lock time. None: smoothing "
        "never restarts (white_zenith_m at every epoch).",
    )

    def sigma(self, el_rad: np.ndarray, white_scale: np.ndarray | None = None) -> np.ndarray:
        """Total one-sigma pseudorange error at elevation el (for weighting), floored at 0.1 m at zenith; white_scale
        multiplies each satellite's white part (a range whose smoothing restarted, SmoothingLock)."""
        if white_scale is None:
            return max(float(np.hypot(self.white_zenith_m, self.correlated_zenith_m)), 0.1) / np.sin(el_rad)
        return np.maximum(np.hypot(self.white_zenith_m * white_scale, self.correlated_zenith_m), 0.1) / np.sin(el_rad)

    def cn0(self, el_rad: np.ndarray) -> np.ndarray:
        """Nominal C/N0 of a direct signal at elevation el, dB-Hz."""
        return self.cn0_horizon_dbhz + (self.cn0_zenith_dbhz - self.cn0_horizon_dbhz) * np.sin(el_rad)


class RangeErrors:
    """Stateful pseudorange error source for all satellites of a constellation, advanced per epoch."""

    def __init__(self, noise: PseudorangeNoise, n_sats: int, rng: np.random.Generator):
        self.noise = noise
        self.rng = rng
        self.slow = rng.standard_normal(n_sats) * noise.correlated_zenith_m
        self.clock_offset_m = rng.uniform(-CLOCK_OFFSET_S, CLOCK_OFFSET_S) * SPEED_OF_LIGHT
        self.clock_drift = rng.normal(0.0, CLOCK_DRIFT_SIGMA) * SPEED_OF_LIGHT
        self.t: float | None = None

    def clock_m(self, t: float) -> float:
        """Receiver clock bias times c at time t, metres."""
        return self.clock_offset_m + self.clock_drift * t

    def advance(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """Step the slow errors to time t; return (zenith slow error, zenith white error) per satellite."""
        n = len(self.slow)
        if self.t is not None:
            phi = np.exp(-(t - self.t) / self.noise.correlation_time_s)
            self.slow = phi * self.slow + np.sqrt(1.0 - phi * phi) * self.noise.correlated_zenith_m * self.rng.standard_normal(n)
        self.t = t
        return self.slow, self.rng.standard_normal(n) * self.noise.white_zenith_m


class SmoothingLock:
    """Carrier smoothing per satellite since it was last acquired (PseudorangeNoise.restart_white_zenith_m). A
    satellite not tracked at an epoch loses lock; when it is tracked again its smoothing filter restarts from the raw
    code, and the window grows by one epoch at a time (a Hatch filter with M = 1, 2, 3, ...), so its range carries,
    beside the smoothed code's own white noise, the mean of the raw noise drawn since lock: sigma_t / sqrt(k) after k
    epochs (sigma_t^2 = raw^2 - smoothed^2), and a mean, so it drifts from epoch to epoch rather than jumping. The
    satellites tracked at the first epoch have been smoothed for long (the receiver was on before the scenario began).
    One per receiver chain, with its own random stream."""

    SETTLED = 1_000_000
    """The epochs since lock of a satellite already tracked when the receiver is first asked (its residual: 0)."""

    def __init__(self, noise: PseudorangeNoise, n_sats: int, rng: np.random.Generator):
        self.noise = noise
        self.rng = rng
        self.epochs = np.zeros(n_sats, dtype=np.int64)
        self.mean = np.zeros(n_sats)
        self.started = False
        raw, smoothed = noise.restart_white_zenith_m or 0.0, noise.white_zenith_m
        self.sigma_t = float(np.sqrt(max(raw * raw - smoothed * smoothed, 0.0)))

    def update(self, sats: np.ndarray, tracked: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Advance the satellites in view (`sats`: their indices; `tracked`: mask over them; every other satellite
        loses lock). Returns, per satellite in view, the zenith error the smoothing has not yet averaged out (m) and
        the factor on the white sigma a receiver weights the range with (its lock time known: 1 once smoothed)."""
        held = np.zeros(len(self.epochs), dtype=bool)
        held[sats[tracked]] = True
        first = self.started is False
        self.started = True
        self.epochs = np.where(held, np.where(first, self.SETTLED, self.epochs + 1), 0)
        draws = self.rng.standard_normal(len(self.epochs)) * self.sigma_t
        k = np.maximum(self.epochs, 1)
        self.mean = np.where(held, self.mean + (draws - self.mean) / k, 0.0)
        smoothed = self.noise.white_zenith_m
        factor = np.sqrt(1.0 + (self.sigma_t / smoothed) ** 2 / k[sats]) if smoothed > 0.0 else np.ones(len(sats))
        return self.mean[sats], factor
