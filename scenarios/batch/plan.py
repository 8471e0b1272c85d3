"""What a sweep runs: `--grid`, `--sample` and `--seeds` over scenarios, expanded into validated runs.

Every point is a scenario file plus `--set`-style overrides and a seed (and with `--fast` its [fast]
variant), loaded (so an unknown key or a bad value fails before anything runs) and identified by its
resolved scenario's hash. `--sample N` places N joint points in the sampled keys' box by a Latin
hypercube (default), scrambled Sobol' points or plain random draws (scipy.stats.qmc; benchmarks/sampling.py
prints how evenly each covers the box).
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import qmc

from scenarios.spec import overrides
from scenarios.spec.library import load, load_fast
from scenarios.spec.scenario import Scenario

SAMPLERS = ("lhs", "sobol", "random")
"""`--sampler`: Latin hypercube (McKay, Beckman & Conover 1979), scrambled Sobol' (Owen 1998), plain random."""


def unit_samples(sampler: str, n: int, dims: int, seed: int) -> np.ndarray:
    """n points in the unit box [0, 1)^dims, from `seed`: a Latin hypercube (each of n equal strata of every
    dimension holds one point), scrambled Sobol' points (n a power of 2: their balance needs it) or plain random."""
    rng = np.random.default_rng(seed)
    if sampler == "lhs":
        return qmc.LatinHypercube(dims, seed=rng).random(n)
    if sampler == "sobol":
        if n < 1 or n & (n - 1):
            below = 1 << (max(n, 1).bit_length() - 1)
            raise ValueError(f"--sampler sobol: N must be a power of 2 for Sobol' points to stay balanced (got {n}; use {below} or {2 * below})")
        return qmc.Sobol(dims, seed=rng).random(n)
    if sampler == "random":
        return rng.random((n, dims))
    raise ValueError(f"--sampler {sampler!r}: use one of {', '.join(SAMPLERS)}")


@dataclass(frozen=True)
class Axis:
    """A grid axis: a scenario key and the values it takes."""

    key: str
    values: tuple

    @staticmethod
    def parse(text: str) -> Axis:
        """'key=v1,v2,...' with TOML values (bare words are strings; commas inside [] and {} do not split)."""
        key, sep, raw = text.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--grid {text!r}: write key=v1,v2,... e.g. lidar.range_noise_m=0.01,0.02")
        values = tuple(overrides.parse_value(v.strip()) for v in _split_top_level(raw) if v.strip())
        if not values:
            raise ValueError(f"--grid {key}: no values (write {key}=v1,v2,...)")
        return Axis(key, values)


@dataclass(frozen=True)
class Range:
    """A sampled key: uniform in [lo, hi] (integers when both bounds are), or log-uniform with ':log'."""

    key: str
    lo: float
    hi: float
    log: bool = False
    integer: bool = False

    @staticmethod
    def parse(text: str) -> Range:
        """'key=lo:hi' or 'key=lo:hi:log'."""
        key, sep, raw = text.partition("=")
        key, parts = key.strip(), raw.strip().split(":")
        usage = f"--sample N {key or 'key'}=lo:hi (or lo:hi:log), e.g. lidar.range_noise_m=0.01:0.05"
        if not sep or not key or len(parts) not in (2, 3) or (len(parts) == 3 and parts[2] != "log"):
            raise ValueError(f"--sample {text!r}: write {usage}")
        bounds = [overrides.parse_value(p.strip()) for p in parts[:2]]
        if not all(isinstance(b, (int, float)) and not isinstance(b, bool) and math.isfinite(b) for b in bounds):
            raise ValueError(f"--sample {key}: bounds must be finite numbers (got {parts[0]!r}, {parts[1]!r})")
        lo, hi = bounds
        log = len(parts) == 3
        if not lo < hi:
            raise ValueError(f"--sample {key}: lo must be below hi (got {lo} .. {hi})")
        if log and lo <= 0:
            raise ValueError(f"--sample {key}: a log-uniform range needs lo > 0 (got {lo})")
        return Range(key, lo, hi, log, integer=not log and isinstance(lo, int) and isinstance(hi, int))

    def values(self, unit: np.ndarray) -> list:
        """The key's values at unit coordinates in [0, 1): linear, log-linear (':log') or, for integer bounds, each of
        lo..hi over an equal share of the unit interval; Python ints or floats, so they render exactly as TOML."""
        u = np.asarray(unit, dtype=float)
        if self.integer:
            span = int(self.hi) - int(self.lo) + 1
            return [int(self.lo) + int(k) for k in np.minimum(np.floor(u * span), span - 1)]
        if self.log:
            scaled = np.exp(math.log(self.lo) + u * (math.log(self.hi) - math.log(self.lo)))
        else:
            scaled = self.lo + u * (self.hi - self.lo)
        return [float(v) for v in np.clip(scaled, self.lo, self.hi)]  # rounding never steps outside the bounds


@dataclass(frozen=True)
class SweepPoint:
    """One run of a sweep: where its scenario comes from, the overrides and seed, and what identifies it."""

    index: int
    source: str
    assignments: tuple[str, ...]
    seed: int
    params: dict
    name: str
    hash: str
    fast: bool = False

    def scenario(self) -> Scenario:
        """The scenario this point runs (its [fast] variant with --fast), validated."""
        return _load(self.source, self.assignments, self.seed, self.fast)

    @property
    def run_name(self) -> str:
        """Its run directory's name: unique in a sweep (the hash covers the seed and every override)."""
        return f"{self.name}-{self.hash}"


@dataclass(frozen=True)
class SweepPlan:
    """Scenarios x grid (cartesian) x samples (joint points of a sampler) x seeds, with fixed overrides for every run;
    fast: each scenario's [fast] variant (a scenario without one is an error)."""

    sources: tuple[str, ...]
    grid: tuple[Axis, ...] = ()
    ranges: tuple[Range, ...] = ()
    samples: int = 0
    seeds: int = 1
    fixed: tuple[str, ...] = ()
    sample_seed: int = 0
    sampler: str = "lhs"
    fast: bool = False
    keys: tuple[str, ...] = field(init=False)

    def __post_init__(self) -> None:
        keys = [a.key for a in self.grid] + [r.key for r in self.ranges]
        for key in keys:
            if keys.count(key) > 1:
                raise ValueError(f"{key}: swept twice (give each key once, in --grid or in --sample)")
        if not self.sources:
            raise ValueError("no scenario to sweep: name one or more library scenarios or .toml files")
        if self.seeds < 1:
            raise ValueError(f"--seeds: at least 1 (got {self.seeds})")
        if self.ranges and self.samples < 1:
            raise ValueError(f"--sample: at least 1 sample (got {self.samples})")
        if not keys and self.seeds == 1:
            raise ValueError("nothing to sweep: give --grid key=v1,v2, --sample N key=lo:hi or --seeds N (N > 1)")
        if "seed" in keys and self.seeds > 1:
            raise ValueError("seed: swept by --grid and repeated by --seeds; use one of them")
        if self.sampler not in SAMPLERS:
            raise ValueError(f"--sampler {self.sampler!r}: use one of {', '.join(SAMPLERS)}")
        object.__setattr__(self, "keys", tuple(keys))

    def combinations(self) -> list[dict]:
        """Each combination of swept values: the grid's cartesian product times the joint samples."""
        grid = [dict(zip([a.key for a in self.grid], values)) for values in itertools.product(*(a.values for a in self.grid))]
        if not self.ranges:
            return grid
        unit = unit_samples(self.sampler, self.samples, len(self.ranges), self.sample_seed)
        drawn = {r.key: r.values(unit[:, j]) for j, r in enumerate(self.ranges)}
        samples = [{key: drawn[key][i] for key in drawn} for i in range(self.samples)]
        return [{**g, **s} for g in grid for s in samples]

    def points(self) -> list[SweepPoint]:
        """Every run, validated (a bad key or value raises ValueError naming it), duplicates dropped."""
        points: list[SweepPoint] = []
        seen: set[str] = set()
        for source in self.sources:
            for params in self.combinations():
                assignments = (*self.fixed, *(overrides.assignment(k, v) for k, v in params.items()))
                base_seed = load(source, set=list(assignments)).seed
                for seed in range(base_seed, base_seed + self.seeds):
                    scenario = _load(source, assignments, seed, self.fast)
                    if scenario.hash in seen:
                        continue
                    seen.add(scenario.hash)
                    points.append(SweepPoint(len(points), source, assignments, seed, params, scenario.name, scenario.hash, self.fast))
        return points


def _load(source: str, assignments: tuple[str, ...], seed: int, fast: bool) -> Scenario:
    return (load_fast if fast else load)(source, set=list(assignments), seed=seed)


def _split_top_level(text: str) -> list[str]:
    """Split at commas outside brackets, braces and quotes."""
    parts, depth, quote, start = [], 0, "", 0
    for i, ch in enumerate(text):
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return parts
