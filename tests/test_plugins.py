"""Plugins: the example package (examples/riverbench_plugins) registered by its entry points, shown,
typed in the JSON Schema and run in the suite; bad plugins are one line at load and recorded
failures inside a run.

The example is installed for each test as pip would install it, without touching the venv: a
dist-info holding its pyproject.toml's entry points in a temporary site directory, which goes on
sys.path and PYTHONPATH with the package's sources (spawned processes inherit both).
"""

import csv
import json
import os
import tomllib
from pathlib import Path

import jsonschema
import pytest
from typer.testing import CliRunner

import fusion
import matcher
from scenarios.batch.suite import run_suite
from scenarios.cli import app
from scenarios.pipeline.runner import run
from scenarios.report.summary import failed_components
from scenarios.spec.library import validate
from scenarios.spec.scenario import default_lists
from scenarios.spec.schema import scenario_json_schema

EXAMPLE = Path(__file__).resolve().parent.parent / "examples" / "riverbench_plugins"
SCENARIO = EXAMPLE / "scenario.toml"


def _install(site: Path, name: str, version: str, entry_points: dict[str, dict[str, str]]) -> None:
    """What pip writes that importlib.metadata reads: a dist-info with METADATA and entry_points.txt."""
    info = site / f"{name.replace('-', '_')}-{version}.dist-info"
    info.mkdir()
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")
    groups = [f"[{group}]\n" + "".join(f"{key} = {value}\n" for key, value in names.items()) for group, names in entry_points.items()]
    (info / "entry_points.txt").write_text("\n".join(groups))


@pytest.fixture
def site(tmp_path, monkeypatch) -> Path:
    """An empty site directory, on sys.path and PYTHONPATH with the example package's sources."""
    site = tmp_path / "site"
    site.mkdir()
    for path in (EXAMPLE, site):
        monkeypatch.syspath_prepend(str(path))
    monkeypatch.setenv("PYTHONPATH", os.pathsep.join(filter(None, [str(site), str(EXAMPLE), os.environ.get("PYTHONPATH")])))
    return site


@pytest.fixture
def installed(site) -> Path:
    """The example package installed by its pyproject.toml's entry points."""
    project = tomllib.loads((EXAMPLE / "pyproject.toml").read_text())["project"]
    _install(site, project["name"], project["version"], project["entry-points"])
    return site


def test_the_example_registers_its_names_and_scenarios_show_prints_their_defaults(installed):
    from riverbench_plugins.icp2d import Icp2d

    assert matcher.available()[-1] == "icp2d" and fusion.available()[-1] == "complementary"
    assert "jump" in fusion.monitors.available() and matcher.params_model("icp2d") is Icp2d.Params
    assert [e["kind"] for e in default_lists()["estimators"]] == fusion.built_in()  # the default stack stays the built-ins
    result = CliRunner().invoke(app, ["scenarios", "show", str(SCENARIO)])
    assert result.exit_code == 0, result.output
    shown = tomllib.loads(result.output)
    icp2d = next(m for m in shown["matchers"] if m["id"] == "icp2d")
    assert icp2d["kind"] == "icp2d" and icp2d["params"] == Icp2d.Params().model_dump()
    estimators = {e["id"]: e for e in shown["estimators"]}
    complementary = estimators["complementary"]
    assert complementary["plugin"] == "riverbench_plugins.complementary:ComplementaryFilter" and "kind" not in complementary
    assert complementary["params"]["position_gain"] == 0.1 and complementary["params"]["antenna"] == [0.0, 0.0, 1.3]
    assert complementary["monitor"] == "jump" and complementary["monitor_params"]["gate_m"] == 4.0
    assert estimators["ekf"]["monitor_params"]["follow_gain"] == 0.05
    check = jsonschema.Draft202012Validator(scenario_json_schema())
    check.validate(tomllib.loads(SCENARIO.read_text()))
    check.validate(shown)
    assert not check.is_valid({"matchers": [{"id": "m", "kind": "icp2d", "params": {"cell": 0.3}}]})  # a typo: not an icp2d key
    assert not check.is_valid({"matchers": [{"id": "m", "kind": "icp2d", "plugin": "riverbench_plugins.icp2d:Icp2d"}]})
    assert not check.is_valid({"estimators": [{"id": "e", "plugin": "complementary"}]})


def test_the_example_scenario_passes_in_the_suite(installed, tmp_path):
    (case,) = run_suite([str(SCENARIO)], tmp_path / "suite", workers=1, fast=True)
    assert case.passed and len(case.expectations) == 3, (case.error, case.expectations)
    metrics = json.loads((Path(case.run_dir) / "metrics.json").read_text())
    assert metrics["run"]["failures"] == [] and ["icp2d"] in metrics["run"]["lanes"][1:]  # matched in a spawned worker
    assert {"complementary", "ekf", "gps_only"} == set(metrics["estimators"])


@pytest.fixture
def broken(site) -> Path:
    """A module that raises when imported and an installed package whose entry point names a missing module."""
    (site / "raising_import.py").write_text('raise RuntimeError("needs a GPU")\n')
    _install(site, "broken-plugins", "1.0", {"riverbench.matchers": {"broken": "broken_plugins.nowhere:Matcher"}})
    return site


def _matcher(**spec) -> dict:
    return {"matchers": [{"id": "m", **spec}]}


def _estimator(**spec) -> dict:
    return {"matchers": [{"id": "m", "kind": "gicp"}], "estimators": [{"id": "e", **spec}]}


@pytest.mark.parametrize(
    "data, needle",
    [
        (_matcher(plugin="no_such_module:Cls"), "matcher plugin 'no_such_module:Cls': cannot import 'no_such_module'"),
        (_matcher(plugin="raising_import:Cls"), "plugin 'raising_import:Cls': cannot import 'raising_import': RuntimeError: needs a GPU"),
        (_matcher(kind="broken"), "matcher plugin 'broken': cannot import 'broken_plugins.nowhere:Matcher'"),
        (_matcher(plugin="plugin_faults:Missing"), "matcher plugin 'plugin_faults:Missing': module 'plugin_faults' has no 'Missing'"),
        (_matcher(plugin="plugin_faults:not_a_class"), "matcher plugin 'plugin_faults:not_a_class': is not a class"),
        (_matcher(plugin="plugin_faults:NoRegister"), "plugin 'plugin_faults:NoRegister': class NoRegister lacks method 'register'"),
        (_matcher(plugin="plugin_faults:FailingMatcher", params={"how": "explode"}), "(plugin_faults:FailingMatcher): how: Input should be"),
        (_estimator(plugin="plugin_faults:HalfEstimator"), "class HalfEstimator lacks method 'add_match', property 'cov'"),
        (_estimator(plugin="plugin_faults:PlainParamsEstimator"), "a class attribute Params subclassing BaseEstimatorParams"),
        (_estimator(kind="ekf", monitor="plugin_faults:NoParams"), "monitor plugin 'plugin_faults:NoParams': class NoParams lacks a"),
        (_estimator(kind="ekf", monitor="plugin_faults:FailingMatcher"), "lacks method 'check', method 'commit', method 'reset', method"),
        (_matcher(kind="gicp", plugin="plugin_faults:FailingMatcher"), "matcher 'm': give kind or plugin, not both"),
        (_estimator(matcher="m"), "estimator 'e': give kind (a registered estimator name) or plugin (a class 'package.module:Class')"),
        (_matcher(kind="plugin_faults:FailingMatcher"), "kind 'plugin_faults:FailingMatcher' is a class path: write plugin = "),
        (_matcher(plugin="icp2d"), "plugin 'icp2d' is not a class path 'package.module:Class'"),
    ],
)
def test_a_bad_plugin_is_one_line_naming_it_at_load(broken, data, needle):
    with pytest.raises(ValueError) as info:
        validate({"name": "t", **data}, "t.toml")
    message = str(info.value)
    assert "\n" not in message and message.startswith("t.toml: ") and needle in message, message


def test_riverbench_run_of_a_bad_plugin_exits_2_before_anything_runs(site, tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text('[[matchers]]\nid = "m"\nplugin = "plugin_faults:NoRegister"\n')
    result = CliRunner().invoke(app, ["run", str(path), "--out", str(tmp_path / "out"), "--quiet"])
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert result.exit_code == 2 and len(lines) == 1 and "plugin_faults:NoRegister" in lines[0], result.output
    assert not (tmp_path / "out").exists()


def test_plugins_that_fail_inside_a_run_are_recorded_from_that_input_on_and_the_run_goes_on(installed, tmp_path):
    faulty = "plugin_faults:FailingEstimator"
    scenario = validate(
        {
            "name": "faults",
            "world": "canal_lock",
            "world_params": {"buildings": False},
            "stretch": {"start_s": 290.0, "end_s": 292.0},
            "matchers": [
                {"id": "icp2d", "kind": "icp2d"},
                {"id": "raises", "plugin": "plugin_faults:FailingMatcher"},
                {"id": "returns_none", "plugin": "plugin_faults:FailingMatcher", "params": {"how": "none"}},
            ],
            "estimators": [
                {"id": "complementary", "kind": "complementary", "matcher": "icp2d"},
                {"id": "match_raises", "plugin": faulty, "matcher": "icp2d"},
                {"id": "bad_verdict", "plugin": faulty, "matcher": "icp2d", "params": {"how": "add_fix"}},
                {"id": "unbuilt", "plugin": faulty, "matcher": "icp2d", "params": {"how": "init"}},
            ],
        }
    )
    result = run(scenario, tmp_path / "run", workers=2, report=False)
    metrics = result.metrics
    assert metrics["run"]["scans"] == 20 and sorted(map(len, metrics["run"]["lanes"])) == [1, 2]  # both lanes ran plugins
    with open(result.out_dir / "gps.csv") as f:
        third_fix = float(list(csv.DictReader(f))[2]["t"])
    third_scan = 290.2
    failures = {f["id"]: f for f in metrics["run"]["failures"]}
    expected = {
        "raises": (third_scan, "plugin_faults:FailingMatcher: RuntimeError: boom at scan 3"),
        "returns_none": (third_scan, "plugin_faults:FailingMatcher: TypeError: register returned a NoneType, not a matcher.MatchResult"),
        "match_raises": (third_scan, f"{faulty}: ZeroDivisionError: bad match"),
        "bad_verdict": (third_fix, f"{faulty}: TypeError: add_fix returned a str, not a fusion.Verdict"),
        "unbuilt": (290.0, f"{faulty}: could not be built: ValueError: cannot start"),
    }
    assert {cid: (pytest.approx(f["stamp"]), f["reason"]) for cid, f in failures.items()} == expected
    assert len(metrics["run"]["failures"]) == len(expected)
    for cid, (stamp, _) in expected.items():
        node = metrics["matchers" if cid in metrics["matchers"] else "estimators"][cid]
        assert node["failed"] and node["failed_at"] == pytest.approx(stamp), cid
    assert not metrics["matchers"]["icp2d"]["failed"] and metrics["matchers"]["icp2d"]["success"] > 0.9
    assert not metrics["estimators"]["complementary"]["failed"]
    said = failed_components(metrics)  # what `riverbench run` prints on its last line, pass or fail
    assert sorted(said) == sorted(f"{cid} at {stamp:.1f} s: {reason}" for cid, (stamp, reason) in expected.items())
    with open(result.out_dir / "scans.csv") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 20 and not any(int(r["raises.ok"]) or int(r["returns_none.ok"]) for r in rows)
