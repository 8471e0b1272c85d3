"""The library's expectations are neither loose nor flaky: against each committed baseline (benchmarks/baseline/*.json),
every seed's value passes its expectation, and no bound is looser than what the seeds' spread gives
(scenarios.report.results.derived_bound). Widening a bound without a baseline that shows why fails here."""

import math
from pathlib import Path

import pytest

import scenarios
from scenarios.report.results import derived_bound
from scenarios.score import baseline as baselines
from scenarios.score.expectations import OPERATORS, Expectation

BASELINES = sorted((Path(__file__).resolve().parent.parent / "benchmarks" / "baseline").glob("*.json"))


def _cases():
    for path in BASELINES:
        base = baselines.load(path)
        for name, runs in sorted(base.scenarios.items()):
            spec = scenarios.load(name)
            for expect in (spec.fast_variant() if base.fast else spec).expect:
                yield pytest.param(path.name, runs, expect, id=f"{path.stem}:{name}:{expect}")


@pytest.mark.parametrize("baseline_name, runs, expect", list(_cases()))
def test_expectation_holds_on_every_baseline_seed_and_is_as_tight_as_the_spread_allows(baseline_name, runs, expect):
    parsed = Expectation.parse(expect)
    metric, op, bound = parsed.path, parsed.op, parsed.value
    values = runs.values(metric, runs.seeds)
    assert all(math.isfinite(v) for v in values), f"{metric} not measured on every seed of {baseline_name}: {values}"
    failing = [(s, v) for s, v in zip(runs.seeds, values) if not OPERATORS[op](v, bound)]
    assert not failing, f"{expect} fails on seeds {failing} of {baseline_name}: the bound is tighter than the scenario's spread"
    derived = derived_bound(values, op, metric)
    if math.isnan(derived):  # every seed gave the same value of a metric without a tolerance: only that it passes is checked
        return
    if op in ("<", "<="):
        assert bound <= derived + 1e-9, f"{expect} is looser than the spread of {baseline_name} gives ({op} {derived:g}): {values}"
    elif op in (">", ">="):
        assert bound >= derived - 1e-9, f"{expect} is looser than the spread of {baseline_name} gives ({op} {derived:g}): {values}"


def test_there_is_a_library_baseline_and_it_covers_the_whole_library():
    base = baselines.load(Path(__file__).resolve().parent.parent / "benchmarks" / "baseline" / "library.json")
    assert set(base.scenarios) == set(scenarios.available()) and base.fast
    # 3 seeds, not 5, until the next refresh: the 5-seed baseline of 709da69 did not reproduce on the machine CI now runs
    # on, and only seeds 0-2 (what CI compares) could be re-measured here in the stop that found it; restore 5
    assert all(len(r.seeds) >= 3 and not r.errors for r in base.scenarios.values())
