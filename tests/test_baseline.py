"""Baselines and their comparison: the verdict on each metric from paired seeds, analytic cases; bad baseline files
are one line and exit 2; compare-baselines exits 1 on a regression and 0 otherwise."""

import json
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from typer.testing import CliRunner

from scenarios.cli import app
from scenarios.score import baseline as baselines
from scenarios.score.metrics import FAMILIES, family_of
from scenarios.score.regression import NOISE_K, compare, judge

runner = CliRunner()
SEEDS = [0, 1, 2, 3, 4]
APE = "estimators.ekf.ape.p95"  # position error: lower is better, 0.05 m or 10%
RECALL = "estimators.ekf.monitor.added_5m.recall"  # fault detection: higher is better, 0.03


def _baseline(values: dict[str, list[float | None]], name: str = "quickstart", seeds=SEEDS, errors=None) -> baselines.Baseline:
    runs = [(s, f"hash{s}", None, (errors or {}).get(s, "")) for s in seeds]
    base = baselines.from_runs({name: runs}, fast=True, overrides=[], provenance={"riverbench": "test"})
    base.scenarios[name].metrics = {k: list(v) for k, v in values.items()}
    return base


def test_every_family_declares_a_direction_and_known_paths_fall_in_the_right_one():
    assert all(f.better in ("lower", "higher", "none") for f in FAMILIES)
    assert family_of(APE).name == "position error" and family_of(APE).better == "lower"
    assert family_of(RECALL).better == "higher"
    assert family_of("matchers.gicp.success").better == "higher"
    assert family_of("gps.error.p95").better == "none"  # what the simulated receiver gave describes the scenario
    assert family_of("run.wall_s").wall_clock


def test_bit_identical_values_are_unchanged_and_flagged_identical():
    v = judge("s", APE, SEEDS, [3.1, 2.9, 3.4, 3.0, 3.2], [3.1, 2.9, 3.4, 3.0, 3.2])
    assert v.verdict == "unchanged" and v.identical and v.change == 0.0


def test_values_are_compared_at_the_precision_metrics_json_publishes():
    """A baseline stored before metrics.json was rounded (scenarios.score.units) stays valid: a run that reproduces it is identical."""
    unrounded = [3.123449, 2.9, 3.40004, 3.0, 3.2]
    v = judge("s", APE, SEEDS, unrounded, [round(x, 4) for x in unrounded])
    assert v.verdict == "unchanged" and v.identical
    assert judge("s", "gps.error.p95", SEEDS, [2.73407854] * 5, [2.7341] * 5).identical  # no direction: not even 'changed'
    assert not judge("s", "gps.error.p95", SEEDS, [2.7340] * 5, [2.7341] * 5).identical


def test_a_worse_value_on_every_seed_is_a_regression_and_a_better_one_an_improvement():
    base = [3.1, 2.9, 3.4, 3.0, 3.2]
    worse = judge("s", APE, SEEDS, base, [b * 1.5 for b in base])
    better = judge("s", APE, SEEDS, base, [b * 0.6 for b in base])
    assert worse.verdict == "regressed" and worse.gating and math.isclose(worse.change, 3.1 * 0.5)
    assert better.verdict == "improved"
    higher = judge("s", RECALL, SEEDS, [0.9] * 5, [0.6] * 5)  # higher is better: a drop regresses
    assert higher.verdict == "regressed"


def test_a_change_within_the_tolerance_or_the_seeds_spread_is_not_called():
    base = np.array([3.0, 5.0, 2.0, 6.0, 4.0])  # spread 1.4826 * MAD = 1.48 m: threshold 2 * 1.48 / sqrt(5) = 1.33 m
    v = judge("s", APE, SEEDS, list(base), list(base + 1.0))
    sigma = 1.4826 * np.median(np.abs(base - np.median(base)))
    assert math.isclose(v.threshold, NOISE_K * sigma / math.sqrt(5)) and v.verdict == "unchanged" and not v.identical
    assert judge("s", APE, SEEDS, [3.0] * 5, [3.04] * 5).verdict == "unchanged"  # under abs_tol 0.05 m
    assert judge("s", APE, SEEDS, [30.0] * 5, [32.9] * 5).verdict == "unchanged"  # under rel_tol 10%
    assert judge("s", APE, SEEDS, [30.0] * 5, [33.1] * 5).verdict == "regressed"


def test_a_median_move_that_most_seeds_do_not_share_is_not_called():
    base = [3.0] * 5
    v = judge("s", APE, SEEDS, base, [4.0, 4.0, 4.0, 2.0, 2.0])  # median +1 m but two seeds of five improved
    assert v.verdict == "unchanged"


def test_outcomes_regress_on_one_seed_and_scenario_descriptions_only_change():
    assert judge("s", "estimators.ekf.failed", SEEDS, [0] * 5, [0, 0, 1, 0, 0]).verdict == "regressed"
    assert judge("s", "vessel.collisions", SEEDS, [0] * 5, [0, 0, 0, 0, 1]).verdict == "regressed"
    assert judge("s", "gps.error.p95", SEEDS, [3.0] * 5, [9.0] * 5).verdict == "changed"
    assert judge("s", APE, SEEDS, [3.0] * 5, [3.0, 3.0, math.nan, 3.0, 3.0]).verdict == "changed"  # measured on one side only


def test_wall_clock_is_judged_on_medians_and_never_fails_the_comparison():
    v = judge("s", "run.wall_s", SEEDS, [10.0] * 5, [30.0] * 5)
    assert v.verdict == "regressed" and not v.gating
    base, now = _baseline({"run.wall_s": [10.0] * 5}), _baseline({"run.wall_s": [30.0] * 5})
    assert not compare(base, now).failed


@given(st.lists(st.floats(0.1, 100.0), min_size=3, max_size=8), st.floats(-0.5, 0.5))
def test_verdicts_follow_the_direction_of_a_uniform_relative_change(base, rel):
    now = [b * (1.0 + rel) for b in base]
    v = judge("s", APE, list(range(len(base))), base, now)
    if v.verdict == "regressed":
        assert rel > 0.09
    elif v.verdict == "improved":
        assert rel < -0.09
    if abs(rel) > 0.11 and min(base) * abs(rel) > 0.05 and np.ptp(base) == 0:
        assert v.verdict == ("regressed" if rel > 0 else "improved")


def test_compare_reports_new_missing_and_failed_scenarios_and_only_failed_runs_fail_it():
    base = _baseline({APE: [3.0] * 5})
    base.scenarios["gone"] = base.scenarios["quickstart"]
    now = _baseline({APE: [3.0] * 5})
    now.scenarios["added"] = now.scenarios["quickstart"]
    c = compare(base, now)
    assert c.new_scenarios == ["added"] and c.missing_scenarios == ["gone"] and not c.failed
    broken = _baseline({APE: [3.0, 3.0, None, 3.0, 3.0]}, errors={2: "RunFailed: at scan 7"})
    c = compare(base, broken)
    assert c.failed and c.failed_runs == {"quickstart": {"2": "RunFailed: at scan 7"}}
    assert "runs failed: quickstart seed 2" in c.sentence()


def test_a_saved_baseline_loads_back_equal_and_keeps_a_metrics_seeds_on_one_line(tmp_path):
    base = _baseline({APE: [3.0, 2.5, None, 4.0, 3.5], RECALL: [1.0] * 5})
    path = tmp_path / "b.json"
    base.save(path)
    assert baselines.load(path) == base
    assert f'"{APE}": [3.0, 2.5, null, 4.0, 3.5]' in path.read_text()
    assert list(tmp_path.iterdir()) == [path]  # no temporary left


def test_flatten_takes_every_number_by_dotted_path_and_skips_provenance_and_expectations():
    tree = {
        "provenance": {"numpy": 2},
        "expectations": [{"pass": True}],
        "run": {"scans": 10, "ok": True, "name": "x"},
        "estimators": {"ekf": {"ape": {"p95": 1.5, "max": float("nan")}}},
    }
    assert baselines.flatten(tree) == {"run.scans": 10.0, "run.ok": 1.0, "estimators.ekf.ape.p95": 1.5, "estimators.ekf.ape.max": None}


@pytest.mark.parametrize(
    "content, problem",
    [
        ("", "not valid JSON"),
        ('{"format": "riverbench-baseline", "format_version": 1, "scenarios": {', "not valid JSON"),
        ('{"some": "thing"}', "not a riverbench baseline"),
        ('{"format": "riverbench-baseline", "format_version": 99}', "format version 99"),
        (
            '{"format": "riverbench-baseline", "format_version": 1, "created_utc": "x", "provenance": {}, "fast": true, '
            '"scenarios": {"q": {"seeds": [0, 1], "hashes": ["a", "b"], "metrics": {"m": [1.0]}}}}',
            "1 values for 2 seeds",
        ),
    ],
)
def test_a_bad_baseline_file_is_one_line_naming_the_problem_and_exit_2(tmp_path, content, problem):
    good = tmp_path / "good.json"
    _baseline({APE: [3.0] * 5}).save(good)
    bad = tmp_path / "bad.json"
    bad.write_text(content)
    for args in (["compare-baselines", str(good), str(bad)], ["suite", "quickstart", "--baseline", str(bad)]):
        result = runner.invoke(app, args)
        assert result.exit_code == 2, result.output
        assert problem in result.output and "Traceback" not in result.output
        assert len(result.output.strip().splitlines()) == 1


def test_a_baseline_of_other_scenarios_is_refused_with_exit_2(tmp_path):
    other = tmp_path / "other.json"
    _baseline({APE: [3.0] * 5}, name="not_in_the_library").save(other)
    result = runner.invoke(app, ["suite", "quickstart", "--baseline", str(other)])
    assert result.exit_code == 2 and "none of these scenarios" in result.output
    mine = tmp_path / "mine.json"
    _baseline({APE: [3.0] * 5}).save(mine)
    result = runner.invoke(app, ["compare-baselines", str(mine), str(other)])
    assert result.exit_code == 2 and "no scenario in common" in result.output


def test_compare_baselines_exits_1_on_a_regression_0_otherwise_and_writes_json_and_junit(tmp_path):
    base, worse, better = (tmp_path / f"{n}.json" for n in ("base", "worse", "better"))
    _baseline({APE: [3.0, 3.2, 2.8, 3.1, 2.9], RECALL: [1.0] * 5}).save(base)
    _baseline({APE: [4.0, 4.2, 3.8, 4.1, 3.9], RECALL: [1.0] * 5}).save(worse)
    _baseline({APE: [2.0, 2.2, 1.8, 2.1, 1.9], RECALL: [1.0] * 5}).save(better)
    result = runner.invoke(app, ["compare-baselines", str(base), str(worse), "--json", str(tmp_path / "c.json"), "--junit", str(tmp_path / "c.xml")])
    assert result.exit_code == 1, result.output
    data = json.loads((tmp_path / "c.json").read_text())
    (moved,) = data["metrics"]
    assert moved["metric"] == APE and moved["verdict"] == "regressed" and moved["baseline_median"] == 3.0 and moved["now_median"] == 4.0
    assert data["counts"]["regressed"] == 1 and data["counts"]["identical"] == 1
    junit = (tmp_path / "c.xml").read_text()
    assert 'classname="riverbench.quickstart.baseline" name="position error"' in junit and "<failure" in junit
    result = runner.invoke(app, ["compare-baselines", str(base), str(better)])
    assert result.exit_code == 0 and "improved" in result.output
    result = runner.invoke(app, ["compare-baselines", str(base), str(base)])
    assert result.exit_code == 0


def test_the_committed_baseline_stays_valid_for_runs_that_publish_rounded_metrics():
    """Every metric of benchmarks/baseline/library.json has a unit, and runs reproducing it, rounded as metrics.json
    now writes them, are judged bit-identical: rounding moves no verdict."""
    from pathlib import Path

    from scenarios.score import units

    base = baselines.load(Path(__file__).resolve().parent.parent / "benchmarks" / "baseline" / "library.json")
    now = base.model_copy(deep=True)
    for runs in now.scenarios.values():
        for metric, values in runs.metrics.items():
            quantity = units.quantity_of(metric)
            assert quantity is not None, metric
            if quantity.decimals is not None:
                runs.metrics[metric] = [None if v is None else round(v, quantity.decimals) for v in values]
    counts = compare(base, now).counts()
    assert counts["unchanged"] == counts["identical"] > 1000 and not counts["regressed"] + counts["improved"] + counts["changed"]


def test_a_baseline_from_another_cpu_model_is_named_as_such():
    from riverbench import provenance

    here = provenance.collect()["cpu"]
    assert isinstance(here, str)
    assert provenance.other_cpu({"cpu": here}) is None
    assert provenance.other_cpu({}) is None  # baselines before the CPU model was recorded
    note = provenance.other_cpu({"cpu": "Some Other CPU @ 1.0GHz"})
    assert (note is not None) == bool(here)
    if note:
        assert "Some Other CPU @ 1.0GHz" in note and here in note
    kernels = provenance.collect()["kernels"]
    assert provenance.other_cpu({"cpu": here, "kernels": kernels}) is None
    other = provenance.other_cpu({"cpu": here, "kernels": "openblas=cpu numpy-disabled=none"})
    assert other is not None and kernels in other  # one model name covers CPUs with and without AVX-512
