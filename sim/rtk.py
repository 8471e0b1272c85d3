"""RTK carrier-phase positioning of a receiver with a base station's corrections: fixed, float, and losing lock.

The code solution (sim.wls and the receiver filter) is what a receiver has before its carrier-phase ambiguities
are resolved. An RTK receiver also tracks each satellite's carrier phase; a satellite whose signal is blocked
(under a bridge) or too weak loses carrier lock and its ambiguity starts again from scratch (a cycle slip).
The float solution's error shrinks from the code solution's as carrier phase accumulates; once enough satellites
have held lock for the convergence time, the integer ambiguities are fixed and the error is centimetres
(baseline dependent). A satellite received only by a reflection (NLOS) carries a biased carrier phase: the
ambiguity validation refuses to fix while one is tracked, so the receiver stays float.

Carrier phase itself is not simulated: fixed and float errors are first-order Gauss-Markov processes with the
datasheet's magnitudes (u-blox ZED-F9P, UBX-17051259), drawn from the receiver's seeded stream.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

CEP50_PER_SIGMA = math.sqrt(2.0 * math.log(2.0))
"""CEP50 of a circular normal error with this per-axis sigma (Rayleigh median: 1.1774 sigma)."""

RTK_FIXED = 4
RTK_FLOAT = 5


class RtkConfig(BaseModel):
    """RTK engine settings (used when the corrections are 'rtk'); defaults: u-blox ZED-F9P with a base 5 km away."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    baseline_m: float = Field(
        5000.0,
        ge=0.0,
        le=100_000.0,
        description="Distance to the base station, m: the '+ 1 ppm' of the datasheet's accuracy grows with it "
        "(5 km: a harbour-side base or a nearby CORS/NTRIP mount point; u-blox ZED-F9P integration manual UBX-18010802: "
        "accuracy degrades with baseline length).",
    )
    fixed_cep_m: float = Field(
        0.01,
        gt=0.0,
        description="Horizontal CEP of an RTK fixed solution at zero baseline, m (u-blox ZED-F9P data sheet UBX-17051259: "
        "'RTK 0.01 m + 1 ppm CEP' horizontal).",
    )
    fixed_ppm: float = Field(1.0, ge=0.0, description="Baseline-dependent part of the fixed CEP, parts per million (ZED-F9P data sheet: + 1 ppm).")
    fixed_vertical_factor: float = Field(
        1.0,
        gt=0.0,
        description="Vertical sigma / horizontal per-axis sigma of a fixed solution "
        "(ZED-F9P data sheet: vertical 0.01 m + 1 ppm R50, as the horizontal).",
    )
    convergence_s: float = Field(
        10.0,
        gt=0.0,
        description="Time from enough satellites holding carrier lock to an RTK fix, s (ZED-F9P data sheet: "
        "'Convergence time RTK < 10 s'; the bench takes the bound).",
    )
    min_fix_sats: int = Field(
        5,
        ge=4,
        description="Satellites in continuous carrier lock needed to fix: 5 give 4 double differences, one more than the "
        "3-D baseline needs, so the integer search can be validated (Teunissen & Montenbruck, Springer Handbook of GNSS, "
        "2017, ch. 23).",
    )
    float_sigma_m: float = Field(
        0.15,
        gt=0.0,
        description="Per-axis sigma of a converged float solution, m: decimetre level (Takasu & Yasuda, 'Development of the "
        "low-cost RTK-GPS receiver with an open source program package RTKLIB', ISGNSS 2009: float errors of decimetres).",
    )
    error_correlation_s: float = Field(
        60.0,
        gt=0.0,
        description="Correlation time of the fixed and float errors, s (residual carrier multipath and differential "
        "troposphere vary over minutes: Teunissen & Montenbruck 2017, ch. 15).",
    )

    @property
    def fixed_sigma_m(self) -> float:
        """Per-axis sigma of the fixed horizontal error whose CEP50 is the datasheet's figure at this baseline."""
        return (self.fixed_cep_m + self.fixed_ppm * 1e-6 * self.baseline_m) / CEP50_PER_SIGMA


class RtkErrors:
    """Fixed and float position errors (ENU, m): first-order Gauss-Markov processes, advanced once per epoch."""

    def __init__(self, config: RtkConfig, rng: np.random.Generator):
        self.rng = rng
        self.tau = config.error_correlation_s
        fixed = config.fixed_sigma_m
        self.sigma = np.array([[fixed, fixed, fixed * config.fixed_vertical_factor], [config.float_sigma_m] * 2 + [2.0 * config.float_sigma_m]])
        self.state = rng.standard_normal((2, 3)) * self.sigma
        self.t: float | None = None

    def advance(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(fixed error, float error) at time t."""
        if self.t is not None:
            phi = math.exp(-(t - self.t) / self.tau)
            self.state = phi * self.state + math.sqrt(1.0 - phi * phi) * self.sigma * self.rng.standard_normal((2, 3))
        self.t = t
        return self.state[0].copy(), self.state[1].copy()


@dataclass
class RtkLock:
    """Carrier lock per satellite and the ambiguity state built on it: fixed once min_fix_sats satellites have each
    held lock for convergence_s, without a reflected-only satellite among the tracked ones."""

    config: RtkConfig
    since: dict[int, float]

    @classmethod
    def start(cls, config: RtkConfig) -> RtkLock:
        return cls(config, {})

    def update(self, t: float, locked: list[int], nlos_tracked: bool) -> tuple[int, float]:
        """GGA quality (4 fixed, 5 float) and how long (s) the float solution has been converging, after this epoch
        with carrier lock on `locked` (ids of the satellites tracked by a direct signal, unique across systems; any other
        loses its lock)."""
        self.since = {sat: self.since.get(sat, t) for sat in locked}
        held = sorted((t - s for s in self.since.values()), reverse=True)
        if len(held) < self.config.min_fix_sats:
            return RTK_FLOAT, 0.0
        age = held[self.config.min_fix_sats - 1]  # the min_fix_sats satellites locked longest have all held this long
        fixed = age >= self.config.convergence_s - 1e-9 and not nlos_tracked
        return (RTK_FIXED if fixed else RTK_FLOAT), age

    def float_weight(self, age: float) -> float:
        """Share of the code solution's error left in the float solution after converging for age s (e-folding
        time convergence_s / 3: 5% left when the fix comes)."""
        return math.exp(-3.0 * age / self.config.convergence_s)
