"""Judge runs against a baseline, metric by metric: unchanged, improved or regressed, the seeds' spread taken into account.

For each scenario and metric the values are paired by seed (the same seed runs the same world,
noise and motion, so a paired difference removes the seed-to-seed spread). With d_s = now_s -
baseline_s, oriented so that positive is worse by the metric family's direction
(scenarios.score.metrics.FAMILIES), a metric

- is *unchanged* when every pair is bit-identical at the precision metrics.json publishes it
  (scenarios.score.units; the bench is deterministic: an untouched tree reproduces every number
  exactly) or when its change is within the threshold;
- *regressed* (or *improved*) when the median of d_s exceeds the threshold
      max(abs_tol, rel_tol x |baseline median|, NOISE_K x sigma_seeds / sqrt(n))
  and at least all but a quarter of the seeds moved that way. sigma_seeds is the baseline's spread
  across seeds (1.4826 x MAD): a change that perturbs every seed's trajectory (a different rounding,
  a reordered sum) moves each seed by about that much, in no consistent direction, and is not called;
- for 0/1 outcomes (a crash, a collision, completion) one seed that got worse is a regression;
- for families without a direction (what the simulated world and sensors produced) any change is
  reported as *changed*, never as a regression;
- wall-clock families (speed, memory) are judged on medians only and never fail the comparison:
  they depend on the machine's load (a benchmark measures them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from riverbench.provenance import describe
from scenarios.score import units
from scenarios.score.baseline import Baseline
from scenarios.score.metrics import Family, family_of

NOISE_K = 2.0
"""How many standard errors of the seeds' own spread a median paired change must exceed to be called."""
VERDICTS = ("regressed", "improved", "changed", "unchanged")


@dataclass(frozen=True)
class MetricVerdict:
    """One metric of one scenario: the baseline's and the new values per seed, and the verdict."""

    scenario: str
    metric: str
    family: Family
    seeds: list[int]
    base: list[float]
    now: list[float]
    verdict: str
    identical: bool
    threshold: float
    change: float  # median over seeds of now - base (NaN when no pair has both values)

    @property
    def gating(self) -> bool:
        """Whether a regression of this metric fails the comparison (not a wall-clock family)."""
        return not self.family.wall_clock

    def as_dict(self) -> dict:
        base, now = np.asarray(self.base), np.asarray(self.now)
        return {
            "scenario": self.scenario,
            "metric": self.metric,
            "family": self.family.name,
            "better": self.family.better,
            "verdict": self.verdict,
            "identical": self.identical,
            "gating": self.gating,
            "seeds": self.seeds,
            "baseline": _json(self.base),
            "now": _json(self.now),
            "baseline_median": _json(_median(base)),
            "baseline_min": _json(_nan(np.nanmin, base)),
            "baseline_max": _json(_nan(np.nanmax, base)),
            "now_median": _json(_median(now)),
            "change": _json(self.change),
            "threshold": _json(self.threshold),
        }


@dataclass
class Comparison:
    """Every metric judged, and what could not be compared: scenarios or seeds on one side only, failed runs."""

    base_provenance: dict
    now_provenance: dict
    verdicts: list[MetricVerdict] = field(default_factory=list)
    new_scenarios: list[str] = field(default_factory=list)
    missing_scenarios: list[str] = field(default_factory=list)
    changed_scenarios: dict[str, list[int]] = field(default_factory=dict)  # name -> seeds whose resolved hash differs
    failed_runs: dict[str, dict[str, str]] = field(default_factory=dict)  # name -> seed -> why it failed now (not before)
    seeds: dict[str, list[int]] = field(default_factory=dict)

    def by(self, verdict: str) -> list[MetricVerdict]:
        return [v for v in self.verdicts if v.verdict == verdict]

    @property
    def regressions(self) -> list[MetricVerdict]:
        """The regressions that fail the comparison (wall-clock ones are reported apart)."""
        return [v for v in self.by("regressed") if v.gating]

    @property
    def failed(self) -> bool:
        """Exit 1: a gating regression, or a run that failed now and not in the baseline."""
        return bool(self.regressions or self.failed_runs)

    def counts(self) -> dict[str, int]:
        out = {v: len(self.by(v)) for v in VERDICTS}
        out["identical"] = sum(v.identical for v in self.verdicts)
        out["moved_within_threshold"] = sum(v.verdict == "unchanged" and not v.identical for v in self.verdicts)
        out["wall_clock_regressed"] = len(self.by("regressed")) - len(self.regressions)
        return out

    def sentence(self) -> str:
        """One line: how many metrics regressed, improved, changed, stayed; what could not be compared."""
        c = self.counts()
        parts = [
            f"{len(self.regressions)} regressed",
            f"{c['improved']} improved",
            f"{c['changed']} changed (no direction)",
            f"{c['unchanged']} unchanged ({c['identical']} bit-identical)",
        ]
        if c["wall_clock_regressed"]:
            parts.append(f"{c['wall_clock_regressed']} wall-clock slower (not gating)")
        extra = []
        if self.failed_runs:
            extra.append(f"runs failed: {', '.join(f'{n} seed {s}' for n, f in self.failed_runs.items() for s in f)}")
        if self.new_scenarios:
            extra.append(f"not in the baseline: {', '.join(self.new_scenarios)}")
        if self.missing_scenarios:
            extra.append(f"in the baseline only: {', '.join(self.missing_scenarios)}")
        if self.changed_scenarios:
            extra.append(f"scenario changed since the baseline: {', '.join(self.changed_scenarios)}")
        return f"against the baseline: {', '.join(parts)}" + (f"; {'; '.join(extra)}" if extra else "")

    def as_dict(self) -> dict:
        """What suite.json and compare-baselines --json carry: counts, provenance of both sides, every non-identical metric."""
        return {
            "counts": self.counts(),
            "failed": self.failed,
            "baseline": self.base_provenance,
            "now": self.now_provenance,
            "baseline_described": describe(self.base_provenance),
            "now_described": describe(self.now_provenance),
            "seeds": self.seeds,
            "new_scenarios": self.new_scenarios,
            "missing_scenarios": self.missing_scenarios,
            "changed_scenarios": self.changed_scenarios,
            "failed_runs": self.failed_runs,
            "metrics": [v.as_dict() for v in self.verdicts if not v.identical],
        }


def compare(base: Baseline, now: Baseline, seeds: int | None = None) -> Comparison:
    """Judge `now` against `base` on the seeds both have (the first `seeds` of them when given)."""
    out = Comparison(base.provenance, now.provenance)
    out.new_scenarios = sorted(set(now.scenarios) - set(base.scenarios))
    out.missing_scenarios = sorted(set(base.scenarios) - set(now.scenarios))
    for name in sorted(set(base.scenarios) & set(now.scenarios)):
        b, n = base.scenarios[name], now.scenarios[name]
        common = [s for s in b.seeds if s in n.seeds][:seeds]
        out.seeds[name] = common
        b_hash, n_hash = dict(zip(b.seeds, b.hashes)), dict(zip(n.seeds, n.hashes))
        if moved := [s for s in common if b_hash[s] != n_hash[s]]:
            out.changed_scenarios[name] = moved
        if failed := {str(s): n.errors[str(s)] for s in common if str(s) in n.errors and str(s) not in b.errors}:
            out.failed_runs[name] = failed
        ok = [s for s in common if str(s) not in b.errors and str(s) not in n.errors]
        for metric in sorted(set(b.metrics) | set(n.metrics)):
            out.verdicts.append(judge(name, metric, ok, b.values(metric, ok), n.values(metric, ok)))
    return out


def judge(scenario: str, metric: str, seeds: list[int], base: list[float], now: list[float]) -> MetricVerdict:
    """The verdict on one metric from its values per seed, paired (see the module's docstring)."""
    family = family_of(metric)
    b, n = published(metric, base), published(metric, now)
    identical = bool(np.array_equal(b, n, equal_nan=True))
    both = np.isfinite(b) & np.isfinite(n)
    d = n[both] - b[both]
    change = float(np.median(d)) if len(d) else math.nan
    threshold = _threshold(family, b[both])
    verdict = "unchanged"
    if identical:
        pass
    elif family.better == "none" or not len(d) or (np.isfinite(b) != np.isfinite(n)).any():
        verdict = "changed"  # no direction, or measured on one side only: reported, never a regression
    else:
        sign = 1.0 if family.better == "lower" else -1.0
        worse = sign * d
        if family.wall_clock:
            worse = np.array([sign * (np.median(n[both]) - np.median(b[both]))])
        verdict = _direction(worse, threshold, family.any_seed)
    return MetricVerdict(scenario, metric, family, list(seeds), list(b), list(n), verdict, identical, threshold, change)


def published(metric: str, values: list[float]) -> np.ndarray:
    """The values at the precision metrics.json publishes the metric (scenarios.score.units), so a baseline recorded
    before metrics.json was rounded compares bit for bit with a run that reproduces it."""
    out = np.asarray(values, dtype=float)
    quantity = units.quantity_of(metric)
    return out if quantity is None or quantity.decimals is None else np.round(out, quantity.decimals) + 0.0


def seed_sigma(values: np.ndarray) -> float:
    """The seeds' spread as a robust standard deviation: 1.4826 x the median absolute deviation from the median."""
    values = np.asarray(values, dtype=float)
    return 1.4826 * float(np.median(np.abs(values - np.median(values))))


def _threshold(family: Family, base: np.ndarray) -> float:
    """max(abs_tol, rel_tol x |median|, NOISE_K x seeds' sigma / sqrt(n)); 0/1 outcomes: any change."""
    if not len(base) or family.any_seed:
        return family.abs_tol
    median = float(np.median(base))
    noise = 0.0
    if len(base) > 1 and not family.wall_clock:
        noise = NOISE_K * seed_sigma(base) / math.sqrt(len(base))
    return max(family.abs_tol, family.rel_tol * abs(median), noise)


def _direction(worse: np.ndarray, threshold: float, any_seed: bool) -> str:
    """regressed / improved / unchanged from the per-seed changes toward worse."""
    if any_seed:
        return "regressed" if (worse > threshold).any() else "improved" if (worse < -threshold).any() else "unchanged"
    agree = len(worse) - len(worse) // 4
    median = float(np.median(worse))
    if median > threshold and (worse > 0).sum() >= agree:
        return "regressed"
    if median < -threshold and (worse < 0).sum() >= agree:
        return "improved"
    return "unchanged"


def _median(values: np.ndarray) -> float:
    return _nan(np.nanmedian, values)


def _nan(fn, values: np.ndarray) -> float:
    return float(fn(values)) if np.isfinite(values).any() else math.nan


def _json(value):
    if isinstance(value, list):
        return [_json(v) for v in value]
    return float(value) if math.isfinite(value) else None
