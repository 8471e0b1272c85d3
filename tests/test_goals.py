"""Goals: the product's promises, judged like expectations but reported apart, met or not, and never failing a run."""

import math

import pytest

import scenarios
from scenarios.report.results import goal_table
from scenarios.score.baseline import Baseline, ScenarioRuns
from scenarios.score.expectations import Expectation
from scenarios.spec.library import validate

METRICS = {"estimators": {"ekf": {"ape": {"p95": 3.0}, "monitor": {"added_5m": {"recall": None}}}, "gps_only": {"ape": {"p95": 2.85}}}}


def test_a_goal_against_another_metric_takes_its_value_plus_the_offset():
    goal = Expectation.parse("estimators.ekf.ape.p95 <= estimators.gps_only.ape.p95 + 0.1")
    assert goal.text == "estimators.ekf.ape.p95 <= estimators.gps_only.ape.p95 + 0.1"
    outcome = goal.check(METRICS)
    assert not outcome.passed and outcome.applicable
    assert "2.95 (estimators.gps_only.ape.p95 2.85 + 0.1)" in outcome.reason
    assert Expectation.parse("estimators.ekf.ape.p95 <= estimators.gps_only.ape.p95 + 0.2").check(METRICS).passed
    assert Expectation.parse("estimators.ekf.ape.p95 > estimators.gps_only.ape.p95 - 1").check(METRICS).passed


def test_a_goal_naming_a_component_the_run_lacks_is_not_applicable():
    """A variant that drops a component the library's goals name (a study setup, --set estimators=[...]) keeps the goals,
    judged n/a; the scenario loads."""
    outcome = Expectation.parse("estimators.nobody.ape.p95 < 3").check(METRICS)
    assert outcome.as_goal()["met"] is None and "no estimator 'nobody' in this run" in outcome.reason
    assert validate({"name": "g", "world": "open_river", "estimators": [], "goals": ["estimators.ekf.ape.p95 < 3"]}).goals


def test_a_goal_on_a_metric_with_nothing_to_measure_is_not_applicable_and_a_missing_one_fails():
    null = Expectation.parse("estimators.ekf.monitor.added_5m.recall >= 0.95").check(METRICS)
    assert null.as_goal()["met"] is None
    missing = Expectation.parse("estimators.ekf.monitor.added_5m.precision >= 0.95").check(METRICS)
    assert missing.as_goal()["met"] is False and "no metric 'precision'" in missing.reason


@pytest.mark.parametrize(
    ("goal", "why"),
    [
        ("estimators.ekf.ape.p95 < three", "metrics start with one of"),
        ("ape < 3", "metrics start with one of"),
        ("estimators.ekf.integrity.misleadnig <= 0.001", "is no metric a run writes"),
        ("estimators.ekf.protection.hpl.p95 < 10", "is no metric a run writes"),
    ],
)
def test_a_goal_naming_an_unknown_component_or_metric_family_is_refused_naming_it(goal, why):
    with pytest.raises(ValueError, match=why):
        validate({"name": "g", "world": "open_river", "goals": [goal]})


def test_goals_leave_the_setup_hash_alone_and_the_fast_variant_carries_its_own():
    plain = validate({"name": "g", "world": "open_river", "fast": {"stretch": {"start_s": 0.0, "end_s": 10.0}}})
    promised = validate(
        {
            "name": "g",
            "world": "open_river",
            "goals": ["estimators.ekf.ape.p95 < 3"],
            "fast": {"stretch": {"start_s": 0.0, "end_s": 10.0}, "goals": ["estimators.ekf.ape.p95 < 1"]},
        }
    )
    assert plain.setup_hash == promised.setup_hash and plain.hash == promised.hash
    assert promised.fast_variant().goals == ["estimators.ekf.ape.p95 < 1"]
    assert "goals" in scenarios.load("quickstart").model_dump() and scenarios.load("quickstart").goals


def test_the_results_table_shows_each_seed_met_or_not():
    runs = ScenarioRuns(
        seeds=[0, 1],
        hashes=["a", "b"],
        metrics={
            "estimators.ekf.ape.p95": [1.0, 4.0],
            "estimators.gps_only.ape.p95": [2.0, 2.0],
            "estimators.ekf.monitor.added_5m.recall": [None, None],
        },
    )
    base = Baseline(scenarios={"s": runs}, fast=True, overrides=[], provenance={}, created_utc="2026-12-02T00:00:00Z")
    table = goal_table(base, {"s": ["estimators.ekf.ape.p95 <= estimators.gps_only.ape.p95 + 0.1", "estimators.ekf.monitor.added_5m.recall >= 0.95"]})
    assert "| 1 (bound 2.1) ✓ | 4 (bound 2.1) ✗ | **no** (1 of 2 seeds) |" in table
    assert "| – | – | n/a |" in table
    assert not math.isnan(runs.values("estimators.ekf.ape.p95", [0])[0])


@pytest.mark.parametrize(
    ("text", "why"),
    [
        ('goals = ["estimators.ekf.ape.p95 < three"]\n', "metrics start with one of"),
        ('goals = ["estimators.ekf.integrity.misleadnig <= 0.001"]\n', "is no metric a run writes"),
        ('[[estimators]]\nid = "ekf"\nkind = "ekf"\nmonitor = "combined_cn0"\nmonitor_params = {gate = 3}\n', "gate"),
        ('[[estimators]]\nid = "ekf"\nkind = "ekf"\nparams = {integrity_risk = 0}\n', "integrity_risk"),
    ],
)
def test_a_bad_goal_monitor_key_or_integrity_risk_is_one_line_and_exit_2(text, why, tmp_path):
    from typer.testing import CliRunner

    from scenarios.cli import app

    path = tmp_path / "bad.toml"
    path.write_text('world = "open_river"\nstretch = {start_s = 0.0, end_s = 5.0}\n' + text)
    result = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "r"), "--quiet"])
    assert result.exit_code == 2 and why in result.output and "Traceback" not in result.output
    assert len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "r").exists()
