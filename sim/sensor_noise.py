"""Inertial sensor noise: white noise, a Gauss-Markov bias and a bias random walk, continuous across batches.

The three terms are the IEEE Std 952 noise model as a simulator realises it: angle (velocity) random
walk N as white noise, the bias instability B as a first-order Gauss-Markov bias of correlation time
T, rate (acceleration) random walk K as a random-walk bias. A datasheet gives B as the flat floor of
the Allan deviation (its minimum divided by 0.664); a Gauss-Markov process has no flat floor, so its
standard deviation is solved for such that the analytic Allan deviation of the sum of the three
terms has its minimum at 0.664 B, and reading the simulated sensor's Allan deviation the way a lab
reads a real one gives back the datasheet figures.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq
from scipy.signal import lfilter

FLICKER_FLOOR = 0.664
"""Allan deviation floor of flicker (bias instability) noise over its coefficient B: sqrt(2 ln 2 / pi) (IEEE Std 952-1997, C.1)."""


def allan_variance(tau: np.ndarray, white: float, gm_sigma: float, gm_tau: float, walk: float) -> np.ndarray:
    """Analytic Allan variance at averaging times tau of white noise (density `white`), a first-order
    Gauss-Markov process (standard deviation gm_sigma, correlation time gm_tau) and a random walk
    (density `walk`): N^2/tau + GM + K^2 tau / 3. The GM term is (s^2 T / tau^2) (2 tau - T (3 - 4 e^-x + e^-2x)), x = tau / T."""
    tau = np.asarray(tau, dtype=float)
    out = white**2 / tau + walk**2 * tau / 3.0
    if gm_sigma > 0:
        x = tau / gm_tau
        out = out + gm_sigma**2 * gm_tau / tau**2 * (2.0 * tau - gm_tau * (3.0 - 4.0 * np.exp(-x) + np.exp(-2.0 * x)))
    return out


def allan_floor(white: float, gm_sigma: float, gm_tau: float, walk: float) -> tuple[float, float]:
    """(minimum Allan deviation, the averaging time where it is) of the three-term model, over 1 ms .. 10^7 s
    (a global minimum on a fine log grid, refined by a parabola through its neighbours)."""
    log_tau = np.linspace(-3.0, 7.0, 4001)
    adev = np.sqrt(allan_variance(10.0**log_tau, white, gm_sigma, gm_tau, walk))
    i = int(np.clip(np.argmin(adev), 1, len(adev) - 2))
    y0, y1, y2 = np.log(adev[i - 1 : i + 2])
    step = log_tau[1] - log_tau[0]
    curve = y0 - 2.0 * y1 + y2
    shift = 0.5 * (y0 - y2) / curve if curve > 0 else 0.0
    return float(np.exp(y1 - 0.25 * (y0 - y2) * shift)), float(10.0 ** (log_tau[i] + shift * step))


def gauss_markov_sigma(white: float, instability: float, gm_tau: float, walk: float) -> float:
    """The Gauss-Markov standard deviation that puts the Allan deviation's minimum at 0.664 x `instability`
    (0 when instability is 0); a ValueError when white noise or the random walk alone already lie above that floor."""
    if instability <= 0:
        return 0.0
    target = FLICKER_FLOOR * instability
    if allan_floor(white, 0.0, gm_tau, walk)[0] >= target:
        raise ValueError(
            f"bias instability {instability:.3g} is below what the white noise and bias random walk alone give "
            f"(Allan floor {allan_floor(white, 0.0, gm_tau, walk)[0] / FLICKER_FLOOR:.3g}): lower the noise or the random walk"
        )
    return float(brentq(lambda s: allan_floor(white, s, gm_tau, walk)[0] - target, 0.0, 10.0 * instability, xtol=1e-12 * instability))


@dataclass(frozen=True)
class NoiseSpec:
    """One sensor triad's stochastic model in SI units: white density, GM sigma and correlation time, random-walk density."""

    white: float
    gm_sigma: float
    gm_tau: float
    walk: float


class TriadNoise:
    """Draws (N, 3) noise samples at a fixed period from a NoiseSpec; the biases carry over from one batch to the next."""

    def __init__(self, spec: NoiseSpec, period: float, rng: np.random.Generator):
        self.spec, self.period, self.rng = spec, float(period), rng
        self._rho = math.exp(-self.period / spec.gm_tau) if spec.gm_sigma > 0 else 0.0
        self.gm = spec.gm_sigma * rng.standard_normal(3)  # stationary start
        self.walk = np.zeros(3)

    def draw(self, n: int) -> np.ndarray:
        """The next n samples of white noise + Gauss-Markov bias + random-walk bias, (n, 3)."""
        s = self.spec
        w = self.rng.standard_normal((n, 9))
        out = (s.white / math.sqrt(self.period)) * w[:, 0:3]
        if s.gm_sigma > 0:
            drive = s.gm_sigma * math.sqrt(1.0 - self._rho**2) * w[:, 3:6]
            gm, _ = lfilter([1.0], [1.0, -self._rho], drive, axis=0, zi=(self._rho * self.gm)[None, :])
            self.gm = gm[-1].copy()
            out += gm
        if s.walk > 0:
            walk = self.walk + np.cumsum(s.walk * math.sqrt(self.period) * w[:, 6:9], axis=0)
            self.walk = walk[-1].copy()
            out += walk
        return out
