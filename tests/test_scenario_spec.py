"""Scenario files: validation naming the key and the file, --set overrides, resolution, hash, expectations."""

import math
import tomllib

import pytest
import tomli_w
from hypothesis import given
from hypothesis import strategies as st

import scenarios
from scenarios.score.expectations import Expectation
from scenarios.spec import overrides
from scenarios.spec.library import validate


def test_every_library_scenario_loads_with_a_description():
    names = scenarios.available()
    assert len(names) >= 8 and "quickstart" in names and "charles_river" in names
    for name in names:
        s = scenarios.load(name)
        assert s.description and "\n" not in s.description
        assert s.expect, f"{name} has no expectations"


@pytest.mark.parametrize(
    "data, needle",
    [
        ({"lidar": {"bogus": 1}}, "t.toml: unknown key 'lidar.bogus'"),
        ({"lidar": {"range_noise_m": "abc"}}, "lidar.range_noise_m"),
        ({"lidar": {"seed": 3}}, "lidar.seed"),
        ({"gnss": {"rate_hz": 100}}, "gnss.rate_hz"),
        ({"world": "atlantis"}, "atlantis"),
        ({"world_params": {"wat": 1}}, "world_params"),
        ({"matchers": [{"id": "m", "kind": "nope"}]}, "nope"),
        ({"matchers": [{"id": "m", "kind": "gicp", "params": {"voxel_m": -1}}]}, "voxel_m"),
        ({"matchers": [{"id": "m", "kind": "gicp", "params": {"voxl_m": 1}}]}, "voxl_m"),
        ({"matchers": [{"id": "a", "kind": "gicp"}, {"id": "a", "kind": "bev3dof"}]}, "'a' is used twice"),
        ({"estimators": [{"id": "e", "kind": "ekf", "matcher": "nope"}]}, "no matcher with id 'nope'"),
        ({"estimators": [{"id": "e", "kind": "ekf", "monitor": "psychic"}]}, "psychic"),
        ({"estimators": [{"id": "e", "kind": "ekf", "params": {"uere_m": -2}}]}, "uere_m"),
        # a combined monitor's members' parameters are checked before the run too (a NaN was dropped silently)
        ({"estimators": [{"id": "e", "kind": "ekf", "monitor_params": {"member_params": {"cn0": {"nlos_bias_m": math.nan}}}}]}, "nlos_bias_m"),
        ({"estimators": [{"id": "e", "kind": "ekf", "monitor_params": {"member_params": {"cn0": {"nlos_bias": 3}}}}]}, "'nlos_bias'"),
        ({"estimators": [{"id": "e", "kind": "ekf", "monitor_params": {"member_params": {"nis": {"gate": 3}}}}]}, "non-member 'nis'"),
        ({"stretch": {"start_s": 10, "end_m": 50}}, "stretch"),
        ({"stretch": {"start_s": 10, "end_s": 5}}, "end after it starts"),
        ({"expect": ["estimators.ekf.ape.p95 <"]}, "metric op number"),
        ({"expect": ["estimators.kalman.ape.p95 < 3"]}, "no estimator with id 'kalman'"),
        ({"expect": ["weather.wind < 3"]}, "metrics start with"),
        ({"control": {"mode": "autopilot"}}, "control.mode"),
        ({"control": {"mode": "closed_loop", "steer_on": "nobody"}}, "control.steer_on"),
    ],
)
def test_bad_scenarios_fail_with_one_line_naming_key_and_file(data, needle):
    with pytest.raises(ValueError) as info:
        validate({"name": "t", **data}, "t.toml")
    message = str(info.value)
    assert "\n" not in message and message.startswith("t.toml: ") and needle in message


def test_resolved_scenario_round_trips_through_toml_with_the_same_hash():
    s = scenarios.load("gps_jump", set=["matchers.gicp.params.voxel_m=0.4", "vessel.sea_state=2"])
    again = validate(tomllib.loads(tomli_w.dumps(s.resolved())))
    assert again.hash == s.hash and again.resolved() == s.resolved()
    assert again.matchers[0].params["voxel_m"] == 0.4 and again.vessel.sea_state == 2
    # every default is written out: the estimators' own parameters and the preset's
    ekf = next(e for e in s.resolved()["estimators"] if e["id"] == "ekf")
    assert ekf["monitor"] == "combined_cn0" and "accel_sigma" in ekf["params"]
    assert "esplanade_offset_m" in s.resolved()["world_params"]


def test_hash_changes_with_what_runs_but_not_with_the_description():
    a = scenarios.load("open_river")
    assert scenarios.load("open_river", set=["description='other words'"]).hash == a.hash
    assert scenarios.load("open_river", seed=1).hash != a.hash
    assert scenarios.load("open_river", set=["lidar.range_noise_m=0.03"]).hash != a.hash


def test_set_reaches_list_items_by_id_and_index_and_reports_a_missing_one():
    s = scenarios.load("quickstart", set=["estimators.ekf.monitor=nis", "estimators.0.params.uere_m=4.0"])
    assert next(e for e in s.estimators if e.id == "ekf").monitor == "nis"
    assert s.estimators[0].params["uere_m"] == 4.0
    with pytest.raises(ValueError, match="no entry 'kalman'"):
        scenarios.load("quickstart", set=["estimators.kalman.monitor=nis"])
    with pytest.raises(ValueError, match="key=value"):
        scenarios.load("quickstart", set=["lidar.range_noise_m"])


@given(
    st.one_of(
        st.integers(-(10**6), 10**6), st.floats(allow_nan=False, allow_infinity=False), st.booleans(), st.lists(st.integers(-100, 100), max_size=4)
    )
)
def test_set_values_are_typed_as_toml(value):
    text = tomli_w.dumps({"v": value}).split("=", 1)[1].strip()
    assert overrides.apply({}, [f"a.b={text}"]) == {"a": {"b": value}}


def test_estimators_know_the_boat_mount_and_antenna_unless_told():
    s = scenarios.load("open_river", set=["vessel.mount_xyz=[0.5, 0.0, 2.0]", "gnss.antenna_offset_m=[0.2, 0.0, 1.5]"])
    for e in s.estimators:
        assert e.params["mount"][0][3] == 0.5 and e.params["mount"][2][3] == 2.0
        assert e.params["antenna"] == [0.2, 0.0, 1.5]


def test_stretch_by_station_is_a_piece_of_the_whole_trajectory():
    import sim
    import worlds

    s = scenarios.load("harvard_beam_bridge")
    trajectory = sim.Trajectory(worlds.load("charles_river"), seed=s.seed)
    t0, t1 = s.stretch.times(trajectory)
    assert s.stretch.start_m is not None and s.stretch.end_m is not None
    assert trajectory.station(t0) == pytest.approx(s.stretch.start_m, abs=1e-3)
    assert trajectory.station(t1) == pytest.approx(s.stretch.end_m, abs=1e-3)


def test_expectations_parse_and_check_against_nested_metrics():
    metrics = {"estimators": {"ekf": {"ape": {"p95": 4.0}, "available": None}}}
    assert Expectation.parse("estimators.ekf.ape.p95 < 6").check(metrics).passed
    failed = Expectation.parse("estimators.ekf.ape.p95 >= 6").check(metrics)
    assert not failed.passed and "4" in failed.reason
    missing = Expectation.parse("estimators.ekf.ape.p99 < 6").check(metrics)
    assert not missing.passed and "p99" in missing.reason and math.isnan(missing.actual)
    assert not Expectation.parse("estimators.ekf.available > 0.5").check(metrics).passed  # null: nothing to measure


def test_fast_variant_takes_its_stretch_and_expectations():
    s = scenarios.load("charles_river")
    fast = s.fast_variant()
    assert fast.fast is None and fast.stretch.start_m == s.fast.stretch.start_m
    assert fast.expect == s.fast.expect and fast.hash != s.hash
    plain = scenarios.load("open_river")
    assert plain.fast_variant() is plain


def test_schema_types_every_section_and_each_kinds_params():
    import jsonschema

    from scenarios.spec.library import path_of
    from scenarios.spec.schema import scenario_json_schema

    schema = scenario_json_schema()
    assert {"world", "stretch", "vessel", "lidar", "gnss", "matchers", "estimators", "expect"} <= set(schema["properties"])
    check = jsonschema.Draft202012Validator(schema)
    for name in scenarios.available():  # the library files as written, and resolved with every default
        check.validate(tomllib.loads(path_of(name).read_text()))
        check.validate(scenarios.load(name).resolved())
    good = {
        "matchers": [{"id": "g", "kind": "gicp", "params": {"voxel_m": 0.5}}],
        "estimators": [{"id": "e", "kind": "ekf", "monitor": "cn0", "monitor_params": {}}],
    }
    check.validate(good)
    wrong = [
        ({"id": "g", "kind": "gicp", "params": {"voxel": 0.5}}, None),  # a typo: not a gicp key
        ({"id": "g", "kind": "gicp", "params": {"voxel_m": "fine"}}, None),
        ({"id": "g", "kind": "icp"}, None),
        (None, {"id": "e", "kind": "ekf", "params": {"monitor": "cn0"}}),  # set on the estimator, not its params
        (None, {"id": "e", "kind": "pf", "monitor": "cn0", "monitor_params": {"gate_sigma": "high"}}),
    ]
    for bad_matcher, bad_estimator in wrong:
        data = {"matchers": [bad_matcher or good["matchers"][0]], "estimators": [bad_estimator or good["estimators"][0]]}
        assert not check.is_valid(data), data
    assert not check.is_valid({"world": "open_river", "world_params": {"no_such_parameter": 1}})


def test_a_random_estimator_draws_from_the_scenario_seed_and_refuses_its_own():
    import numpy as np

    draws = []
    for seed in (0, 0, 1):
        scenario = scenarios.load("open_river", seed=seed)
        pf = next(e for e in scenario.estimators if e.kind == "pf")
        assert "seed" not in pf.params and "seed" not in scenario.resolved()["estimators"][3]["params"]
        draws.append(pf.build(scenario.seed).rng.random(4))
    assert np.array_equal(draws[0], draws[1]) and not np.array_equal(draws[0], draws[2])
    with pytest.raises(ValueError, match="params.seed: every component takes the scenario's top-level seed"):
        scenarios.load("open_river", set=["estimators.pf.params.seed=3"])
