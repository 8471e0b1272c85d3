"""`riverbench study`: the command's directory on a few seconds of the route (files, study.json keys, every finding with
checks and a verdict), the verdict rules on hand-made numbers, nothing written when interrupted or on bad input (exit 2);
slow: the real study over the whole route gives every finding a number and a verdict."""

from __future__ import annotations

import json
import math
import os
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from scenarios.cli import app
from scenarios.study import plots, verdicts
from scenarios.study import study as study_module
from scenarios.study.findings import FINDINGS, by_key
from scenarios.study.matcher_findings import compose, success_curve
from scenarios.study.plan import MATCHERS, StudyPlan, burst_starts, chain_pieces, parse_stretch, study_scenario
from scenarios.study.setups import SETUPS
from scenarios.study.verdicts import Check, verdict

runner = CliRunner()
KEYS = [f.key for f in FINDINGS]
TINY = "1700:1706"
"""Three seconds under the Harvard Bridge: a blackout, points in the study's band, a few bursts."""


STACK = textwrap.dedent(
    """
    name = "my_stack"
    world = "charles_river"

    [[matchers]]  # the guide's worked example: KISS-ICP's own pipeline, pinned to one thread (same bytes every run)
    id = "kiss"
    kind = "command"
    command = \"\"\"env 'kiss_icp_registration={{"max_num_threads": 1}}' 'kiss_icp_data={{"max_range": {max_range}}}' \
    'kiss_icp_mapping={{"voxel_size": {voxel_size}}}' kiss_icp_pipeline {recording}\"\"\"
    recording = "rosbag2"
    output = "results/**/*_poses_tum.txt"
    anchor = "se3"
    params = { max_range = 100.0, voxel_size = 0.5 }

    [[estimators]]  # the ROS 2 example's converter on the recording's own truth topic: an exact estimator
    id = "bag_truth"
    kind = "command"
    command = "%s %s/ros2/odometry_to_tum.py {recording} /ground_truth/odom {out}/truth.tum"
    recording = "rosbag2"
    output = "out/truth.tum"
    """
) % (sys.executable, Path(__file__).resolve().parent.parent / "examples")
"""A scenario file with a command matcher and a command estimator, for `riverbench study --scenario`."""


@pytest.fixture(scope="module")
def tiny(tmp_path_factory):
    """The tiny study with the command components of STACK beside the built-ins (its own recording cache)."""
    tmp = tmp_path_factory.mktemp("study")
    out = tmp / "tiny"
    (tmp / "stack.toml").write_text(STACK)
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("RIVERBENCH_CACHE", str(tmp / "cache"))
        patch.setenv("PATH", f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")  # kiss_icp_pipeline
        args = ["study", "--out", str(out), "--stretch", TINY, "--workers", "1", "--quiet", "--scenario", str(tmp / "stack.toml")]
        result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    return out, json.loads((out / "study.json").read_text())


def test_the_tiny_study_writes_its_directory(tiny):
    out, tree = tiny
    assert {p.name for p in out.iterdir()} == {"report.md", "report.html", "study.json", "plots", "components"}
    assert all(p.suffix == ".png" and p.read_bytes()[:4] == b"\x89PNG" for p in (out / "plots").iterdir())
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".")]  # no temporary left beside it
    html = (out / "report.html").read_text()
    assert "data:image/png;base64," in html and 'src="plots/' not in html  # self-contained
    md = (out / "report.md").read_text()
    for f in FINDINGS:
        assert f"{f.key}. {f.title}" in md


def test_study_json_has_every_finding_with_checks_and_a_verdict(tiny):
    _, tree = tiny
    assert {"provenance", "citation", "scenario", "plan", "findings", "run"} <= set(tree)
    assert tree["scenario"]["name"] == "charles_river" and list(tree["findings"]) == KEYS
    for key, f in tree["findings"].items():
        assert f["verdict"] in verdicts.VERDICTS
        assert f["study"] == json.loads(json.dumps(by_key()[key].figures))  # the study's figures, from the one table
        assert {"title", "claim", "headline", "checks", "measured"} <= set(f)
        assert f["verdict"] == verdict([Check(**c) for c in f["checks"]])
    m = {k: f["measured"] for k, f in tree["findings"].items()}
    assert m["a"]["structures"]["harvard_bridge"]["passage_s"] > 0  # the stretch is under its deck
    assert set(m["e"]) == {"pcl6d", "bev3dof", "kiss_icp", "gicp"} and all(v["registrations"] > 0 for v in m["e"].values())
    assert m["h"]["scans"] == tree["plan"]["chain_scans"] > 5  # every third revolution of the stretch (9), chained
    # both setups side by side: each finding's verdict and cause under each, the first setup's at the top level
    assert list(tree["setups"]) == ["bench", "field"] and tree["setups"]["field"]["receiver"] == {"profile": "sbas_gps"}
    for f in tree["findings"].values():
        assert list(f["setups"]) == ["bench", "field"]
        assert f["verdict"] == f["setups"]["bench"]["verdict"]
        for node in f["setups"].values():
            assert node["verdict"] == verdict([Check(**c) for c in node["checks"]]) and node["cause"].endswith(".")
    field = tree["findings"]["e"]["setups"]["field"]["measured"]
    assert set(field) == {"pcl6d", "bev3dof", "kiss_icp", "gicp"}  # the field's Method 1 reported as pcl6d
    assert "pcl6d_field" not in json.dumps(tree["findings"]["f"]) and "pcl6d_field" not in (tiny[0] / "report.md").read_text()


def test_the_matcher_figures_show_the_field_setups_method1_beside_the_benchs(tiny):
    _, tree = tiny
    field = tree["findings"]["f"]["setups"]["field"]["measured"]
    assert plots.beside(tree, "f")["matchers"]["pcl6d (field)"] == field["matchers"]["pcl6d"]
    assert plots.beside(tree, "g")["pcl6d (field)"] == tree["findings"]["g"]["setups"]["field"]["measured"]["pcl6d"]
    assert plots.beside(tree, "g")["pcl6d"] == tree["findings"]["g"]["measured"]["pcl6d"]  # the bench's own, as it was
    rows = [{"matcher": m} for m in ("pcl6d", "gicp", "pcl6d (field)")]
    assert plots.plotted(rows) == [*MATCHERS, "pcl6d (field)"] and plots.plotted(rows[:2]) == list(MATCHERS)


def test_the_verdict_rules_on_hand_made_numbers():
    yes, no, none = (Check("c", "s", "m", v) for v in (True, False, None))
    assert verdict([yes, yes, none]) == "agrees"
    assert verdict([no, no]) == "disagrees"
    assert verdict([yes, no, none]) == "partly"
    assert verdict([none]) == verdict([]) == "unmeasured"
    d = by_key()["d"]
    good = {"fixes": 100, "error": {"p95": 0.8, "median": 0.4}}
    assert verdict(verdicts.checks_d(good, d)) == "agrees"
    assert verdict(verdicts.checks_d({"fixes": 100, "error": {"p95": 1.5, "median": 0.6}}, d)) == "partly"
    assert verdict(verdicts.checks_d({"fixes": 100, "error": {"p95": 3.0, "median": 1.2}}, d)) == "disagrees"
    assert verdict(verdicts.checks_d({"fixes": 0, "error": {"p95": math.nan, "median": math.nan}}, d)) == "unmeasured"
    h = by_key()["h"]
    node = {"matcher": "kiss_icp", "distance_m": 5000.0, "compass_p95_deg": 2.0}
    assert verdict(verdicts.checks_h({**node, "drift_end_deg": -20.0}, h)) == "agrees"
    assert verdict(verdicts.checks_h({**node, "drift_end_deg": 5.0}, h)) == "partly"  # beyond the compass, below the study's order
    assert verdict(verdicts.checks_h({**node, "drift_end_deg": 1.0}, h)) == "disagrees"
    e = by_key()["e"]
    rates = {
        "pcl6d": {"hz": 5.0, "spearman_cpu_seconds_points": 0.6, "error_m_median": 0.02, "unresolved": 0.05},
        "bev3dof": {"hz": 50.0, "error_m_median": 0.05, "unresolved": 0.20},
    }
    assert verdict(verdicts.checks_e(rates, e)) == "agrees"
    assert verdict(verdicts.checks_e({**rates, "pcl6d": {**rates["pcl6d"], "hz": 12.0}}, e)) == "partly"


def test_the_success_curve_counts_per_bin_and_band():
    rows = [{"matcher": "m", "points": p, "ok": ok} for p, ok in [(500, False), (1500, False), (6500, True), (6900, True), (30000, True)]]
    curve = success_curve(rows, ["m"], (6000, 27000))
    s = curve["matchers"]["m"]
    assert curve["bin_edges"][:3] == [0, 1000, 2000] and sum(s["count"]) == 5
    assert s["count"][6] == 2 and s["success"][6] == 1.0 and s["success"][0] == 0.0
    assert (s["band_count"], s["band_success"], s["below_count"], s["below_success"]) == (2, 1.0, 2, 0.0)


def test_plan_helpers():
    assert parse_stretch("10:20.5") == (10.0, 20.5)
    for bad in ("abc", "20:10", "1:2:3", "-5:3"):
        with pytest.raises(ValueError, match="--stretch"):
            parse_stretch(bad)
    assert chain_pieces(11, 2) == [(0, 5), (5, 10)]  # consecutive pieces share their boundary scan
    assert list(burst_starts(0.0, 25.0, 0.1, StudyPlan(burst_spacing_s=10.0, burst_scans=3))) == [0.0, 10.0, 20.0]
    with pytest.raises(ValueError, match="study plan"):
        StudyPlan(burst_scans=1)


def test_pieces_compose_into_one_chain():
    import numpy as np

    from scenarios.score.record import MatcherTrack
    from scenarios.study.tasks import ChainPiece

    def pose(x, yaw):
        T = np.eye(4)
        T[:2, :2] = [[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]]
        T[0, 3] = x
        return T

    def piece(t, truth, chained):
        n = len(t)
        track = MatcherTrack(np.ones(n, bool), np.zeros(n, bool), np.zeros(n, bool), np.zeros(n, int), np.zeros(n), np.array(chained))
        return ChainPiece(np.array(t), np.array(truth), track)

    # truth turns 0.1 rad per step; each piece's odometry starts at the truth and over-turns by 0.01 rad per step
    truth = [pose(i, 0.1 * i) for i in range(5)]
    a = piece([0, 1, 2], truth[:3], [pose(i, 0.11 * i) for i in range(3)])
    b = piece([2, 3, 4], truth[2:], [truth[2] @ pose(0, 0.11 * k) for k in range(3)])
    t, _, chained, ok = compose([a, b])
    assert list(t) == [0, 1, 2, 3, 4] and ok.all()
    yaw = np.arctan2(chained[:, 1, 0], chained[:, 0, 0])
    np.testing.assert_allclose(yaw, 0.11 * np.arange(5), atol=1e-12)  # the drift carries across the boundary


@pytest.mark.parametrize(
    "args, needle",
    [
        (["--stretch", "abc"], "--stretch"),
        (["--stretch", "0:999999"], "stretch"),
        (["--seed", "-1"], "seed"),
        (["--setup", "nope"], "--setup"),
        (["--set", "vessel.wind_wave=1"], "vessel.wind_wave"),
        (["--set", "seed=3"], "--seed"),
        (["--set", "nokey"], "key=value"),
        (["--set", "expect=[]"], "expect"),
        (["--set", "matchers=[]"], "matchers.gicp.params"),
        (["--set", 'world="canal_lock"'], "charles_river"),
        (["--set", "vessel.wind_waves={wind_mps = -1.0, fetch_m = 3000.0}"], "wind_mps"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, args, needle):
    out = tmp_path / "out"
    result = runner.invoke(app, ["study", "--out", str(out), "--workers", "1", "--quiet", *args])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in result.output
    assert not out.exists() and not list(tmp_path.iterdir())


def test_set_changes_the_studys_conditions_and_a_setups_receiver_keeps_its_own_fields():
    chop = "vessel.wind_waves={wind_mps = 5.5, fetch_m = 3000.0}"
    field = study_scenario(receiver=SETUPS["field"].receiver, overrides=[chop, "gnss.rate_hz=10.0", 'gnss.profile="consumer"'])
    assert field.vessel.wind_waves is not None and field.vessel.wind_waves.fetch_m == 3000.0
    assert field.gnss.rate_hz == 10.0 and field.gnss.constellations == ("GPS",)  # the setup's sbas_gps wins on the profile
    plain = study_scenario()
    assert plain.vessel.wind_waves is None and study_scenario(overrides=[chop]).hash != plain.hash


def test_a_non_empty_out_dir_is_refused(tmp_path):
    (tmp_path / "keep.txt").write_text("x")
    result = runner.invoke(app, ["study", "--out", str(tmp_path), "--stretch", TINY, "--workers", "1", "--quiet"])
    assert result.exit_code == 2 and "not empty" in result.output
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]


def test_an_interrupted_study_leaves_nothing(tmp_path, monkeypatch):
    calls, original = [], study_module.run_task

    def interrupted(job):
        calls.append(job[0])
        if len(calls) == 1:  # Ctrl-C as the first job starts
            raise KeyboardInterrupt
        return original(job)

    monkeypatch.setattr(study_module, "run_task", interrupted)
    result = runner.invoke(app, ["study", "--out", str(tmp_path / "out"), "--stretch", TINY, "--workers", "1", "--quiet"])
    assert result.exit_code == 130 and "nothing written" in result.output
    assert not list(tmp_path.iterdir())  # neither the directory nor its temporary


@pytest.mark.slow
def test_the_real_study_gives_every_finding_a_number_and_a_verdict(tmp_path):
    out, tree = study_module.run_study(tmp_path / "study")
    assert (out / "report.html").exists()
    for key, f in tree["findings"].items():
        assert f["verdict"] in ("agrees", "partly", "disagrees"), (key, f["verdict"], f["headline"])
        assert any(c["holds"] is not None for c in f["checks"]), key
    m = {k: f["measured"] for k, f in tree["findings"].items()}
    assert len(m["a"]["structures"]) >= 5  # every bridge and the lock on the route
    assert m["d"]["fixes"] > 100 and m["d"]["error"]["p95"] is not None
    assert m["e"]["pcl6d"]["hz"] is not None and m["e"]["bev3dof"]["hz"] is not None
    assert m["h"]["drift_end_deg"] is not None and m["h"]["scans"] == tree["plan"]["chain_scans"]


def test_the_chains_heading_is_integrated_as_a_planar_filter_does_so_its_tilt_stays_out():
    import numpy as np
    from scipy.spatial.transform import Rotation

    from scenarios.study.matcher_findings import planar_heading, tilt_deg

    def poses(yaw_deg, pitch_deg):
        out = np.tile(np.eye(4), (len(yaw_deg), 1, 1))
        out[:, :3, :3] = Rotation.from_euler("ZY", np.c_[yaw_deg, pitch_deg], degrees=True).as_matrix()
        return out

    k = np.arange(121.0)
    level = poses(np.full_like(k, 30.0), np.zeros_like(k))
    pitching = poses(np.full_like(k, 30.0), k)  # a chain whose pitch drifts to 120 deg, its heading held
    assert np.allclose(planar_heading(pitching), np.radians(30.0))
    assert np.allclose(tilt_deg(pitching, level), k)
    turning = poses(3.0 * k, np.zeros_like(k))  # a level chain turning through 360 deg: its heading, unwrapped
    assert np.allclose(planar_heading(turning), np.radians(3.0 * k))
    gap = turning.copy()
    gap[10:12] = np.nan  # failed scans: the step is taken across them
    h = planar_heading(gap)
    assert np.isnan(h[10:12]).all() and np.allclose(np.delete(h, [10, 11]), np.delete(np.radians(3.0 * k), [10, 11]))


def test_the_setups_change_only_the_receiver_and_method1():
    from scenarios.study.plan import study_scenario
    from scenarios.study.setups import FIELD_METHOD1_ID, SETUPS, parse_setup

    assert parse_setup("both") == ("bench", "field") and parse_setup("field") == ("field",)
    bench = study_scenario()
    field = study_scenario(receiver=SETUPS["field"].receiver, field_method1=SETUPS["field"].method1)
    assert bench.gnss.constellations == ("GPS", "GLONASS", "GALILEO", "BEIDOU") and field.gnss.constellations == ("GPS",)
    # and the field's receiver restarts its carrier smoothing at reacquisition (sim.pseudorange.SmoothingLock)
    same = {"profile": True, "constellations": True, "noise": {"restart_white_zenith_m"}}
    assert field.gnss.model_dump(exclude=same) == bench.gnss.model_dump(exclude=same)
    assert field.gnss.noise.restart_white_zenith_m == 0.6 and bench.gnss.noise.restart_white_zenith_m is None
    assert [m.id for m in field.matchers] == [m.id for m in bench.matchers] + [FIELD_METHOD1_ID]
    method1 = field.matcher_spec(FIELD_METHOD1_ID)
    assert method1.ref == "pcl6d" and method1.params["skip_prealign_max_dt_s"] == 0.0  # pre-aligned on every pair
    # its RANSAC as PCL's SampleConsensusPrerejective runs it: a fixed 5,000 hypotheses (PCL's default), no early exit
    assert method1.params["ransac_until"] == "max_iterations" and method1.params["ransac_max_iterations"] == 5000
    changed = ("skip_prealign_max_dt_s", "ransac_until", "ransac_max_iterations")
    assert {k: v for k, v in method1.params.items() if k not in changed} == {
        k: v for k, v in field.matcher_spec("pcl6d").params.items() if k not in changed
    }


def test_open_water_leaves_out_the_epochs_a_reflection_reaches_and_the_filter_remembers():
    import numpy as np

    from scenarios.score.record import FixTable
    from scenarios.study.gnss_findings import OPEN_WATER_AFTER_S, open_water
    from scenarios.study.tasks import GnssSample

    n, period = 200, 0.2
    t = np.arange(n) * period
    zeros = np.zeros((n, 3))
    nothing = zeros[:, 0]
    fixes = FixTable(t, np.full(n, 2), zeros, nothing, nothing, nothing, np.full(n, 8), np.ones(n), zeros, zeros, np.zeros(n, bool), {}, {})
    reflected = np.zeros(n, int)
    reflected[20:25] = 1  # 1.0 s of code multipath from t = 4.0 s
    g = GnssSample(fixes, np.full(n, 8), np.arange(n) * 0.4, period, reflected)
    assert open_water(g, [], []).all()  # the route's open water: reflections on direct signals kept
    mask = open_water(g, [], [], reflections=False)
    gone = (t >= 4.0) & (t < 5.0 + OPEN_WATER_AFTER_S)  # the span and the receiver filter's memory after it
    assert np.array_equal(mask, ~gone)


def test_finding_g_judges_shares_of_points_not_of_feature_matches():
    g = by_key()["g"]
    node = {"pcl6d": {"outlier_share": {"median": 0.05, "p90": 0.08, "n": 50}, "prealign_rejected_share": {"median": 0.6, "p90": 0.7, "n": 50}}}
    checks = verdicts.checks_g(node, g)
    assert [c.claim.split(":")[0] for c in checks] == ["pcl6d outlier_share"] and verdict(checks) == "agrees"


def test_the_field_setup_judges_matching_on_the_studys_own_two_methods():
    """Findings f and g are about what the study ran (Method 1, pcl6d; Method 2, bev3dof): under the field setup a
    modern matcher's success below the band is reported, not held against the study's finding."""
    from scenarios.study.setups import SETUPS

    f = by_key()["f"]
    outcome = {"pcl6d": False, "bev3dof": False, "gicp": True}  # below the band; every one succeeds in it
    rows = [{"matcher": mid, "points": pts, "ok": ok} for mid in outcome for pts, ok in ((3000, outcome[mid]), (9000, True)) for _ in range(12)]
    m = success_curve(rows, ["pcl6d", "bev3dof", "gicp"], f.figures["points_band"])
    every = verdicts.checks_f(m, f)
    field = verdicts.checks_f(m, f, SETUPS["field"].judged_matchers)
    assert verdict(every) == "partly" and verdict(field) == "agrees"
    assert {c.claim.split()[0] for c in field} == {"pcl6d", "bev3dof"}
    assert SETUPS["bench"].judged_matchers is None


def test_the_cause_of_finding_a_names_the_deck_a_fix_held_under():
    from scenarios.study.causes import cause

    held = {"blackout_s": 0.0, "lost_share_under": 0.0, "los_min_under": 6}
    lost = {"blackout_s": 4.0, "lost_share_under": 0.8, "los_min_under": 2}
    text = cause("a", "bench", "partly", {"structures": {"bu_bridge": held, "harvard_bridge": lost}})
    assert "Under bu_bridge" in text and "fewest: bu_bridge 6" in text and "harvard_bridge 80%" in text
    assert cause("a", "field", "agrees", {"structures": {"harvard_bridge": lost}}).startswith("Every deck cuts the fix (sbas_gps)")
    assert cause("d", "bench", "unmeasured", {}) == "not enough data on this stretch to name the cause."


def test_the_cause_of_finding_b_counts_the_outages_that_end_on_reflected_signals():
    from scenarios.study.causes import cause

    def outage(reflected: int, first_max_m: float, sats: int) -> dict:
        coast = {"settle_s": 0.2, "coasted_s": 3.0, "coast_end_error_m": 1.5}
        return {**coast, "first_sats": sats, "first_max_m": first_max_m, "first_reflected": reflected}

    m = {"outages": [outage(3, 15.7, 4), outage(0, 0.9, 5), outage(0, 0.5, 6)], "open_water_p95_m": 0.8, "first_fixes": 10}
    bench, field = cause("b", "bench", "partly", m), cause("b", "field", "disagrees", m)
    assert "after 1 of 3 outages some of the first 10 fixes use a satellite received only by its reflection" in bench
    assert "off by up to 15.7 m" in bench and "after 2 they use direct signals alone, on 5-6 satellites (off by up to 0.5-0.9 m)" in bench
    assert "tracking GPS alone" in field and "tracking GPS alone" not in bench
    older = {**m, "outages": [{k: v for k, v in r.items() if k != "first_reflected"} for r in m["outages"]]}
    assert cause("b", "bench", "partly", older).endswith("What the first fixes are made of: not recorded.")


def test_command_components_are_scored_in_the_findings_they_apply_to(tiny):
    """kiss_icp_pipeline (a command matcher) in e, f and h; an exact command estimator in b and d; none in a, c, g; each
    with its own verdict under each setup, the built-ins' findings as without them."""
    out, tree = tiny
    assert {cid: c["findings"] for cid, c in tree["components"].items()} == {"kiss": ["e", "f", "h"], "bag_truth": ["b", "d"]}
    for key, f in tree["findings"].items():
        expected = {"e": {"kiss"}, "f": {"kiss"}, "h": {"kiss"}, "b": {"bag_truth"}, "d": {"bag_truth"}}.get(key, set())
        assert set(f.get("components", {})) == expected, key
        for by_setup in f.get("components", {}).values():
            assert list(by_setup) == ["bench", "field"]
            for node in by_setup.values():
                assert node["verdict"] == verdict([Check(**c) for c in node["checks"]]) and node["checks"], key
    assert set(tree["findings"]["e"]["measured"]) == {"pcl6d", "bev3dof", "kiss_icp", "gicp"}  # the built-ins' node, untouched
    kiss = tree["components"]["kiss"]["runs"]["bench"]
    assert kiss["failed"] is False and kiss["coverage"] == 1.0 and kiss["ape"]["rmse"] < 0.5
    assert set(tree["components"]["kiss"]["runs"]) == {"bench"}  # a matcher runs once: the setups differ in the receiver
    assert set(tree["components"]["bag_truth"]["runs"]) == {"bench", "field"}
    assert tree["components"]["bag_truth"]["runs"]["field"]["ape"]["max"] == 0.0
    e = tree["findings"]["e"]["components"]["kiss"]["bench"]["measured"]
    scans = json.loads((out / "components" / "bench" / "metrics.json").read_text())["run"]["scans"]
    assert e["registrations"] == scans - 1 and e["unresolved"] == 0.0 and e["error_m_median"] < 0.1 and e["hz"] > 0
    f = tree["findings"]["f"]["components"]["kiss"]["bench"]["measured"]["matchers"]["kiss"]
    assert f["band_count"] + f["below_count"] <= scans - 1 and sum(f["count"]) == scans - 1 and len(f["accurate"]) == len(f["count"])
    assert f["band_accurate"] > 0.9  # KISS-ICP at 100 m: its steps within 5 cm and 0.5 deg of the true motion
    h = tree["findings"]["h"]["components"]["kiss"]["bench"]["measured"]
    assert h["matcher"] == "kiss" and h["scans"] == scans and abs(h["drift_end_deg"]) < 5
    md = (out / "report.md").read_text()
    assert "## Command components" in md and "| bench: kiss (command) |" in md and "| kiss | matcher | bench | e, f, h | ok |" in md
    assert (out / "components" / "bench" / "commands" / "kiss.stderr.log").is_file()


def test_an_exact_command_estimator_has_no_error_at_any_receiver_epoch(tiny):
    """What findings b and d read of a command estimator: its error at each receiver epoch (the converter of the
    recording's own truth topic: zero wherever a scan precedes the epoch within a revolution)."""
    import scenarios
    from scenarios.study import components, tasks

    run_dir = tiny[0] / "components" / "bench"
    scenario = scenarios.load(run_dir / "scenario.toml")
    tree = json.loads((run_dir / "metrics.json").read_text())
    component = components.Component("estimators", scenario.command_estimators[0])
    scored = components.scored(run_dir, scenario, tree, component, {})
    g = tasks.gnss(scenario)
    mine = components.estimator_sample(scored, g, assemble_trajectory(scenario))
    have = mine.fixes.quality == 1
    assert have.mean() > 0.9 and mine.fixes.horizontal_error[have].max() < 1e-6


def assemble_trajectory(scenario):
    from scenarios.pipeline.assembly import assemble

    return assemble(scenario).trajectory


def test_kiss_icp_pipeline_pinned_to_one_thread_gives_the_same_bytes_when_crippled(tiny, tmp_path):
    """A max_range that cripples KISS-ICP (10 m: few points, an ill-conditioned fit) makes its answer chaotic; with its
    registration's TBB reduction on one thread (kiss_icp_registration's max_num_threads) two runs write the same bytes."""
    import scenarios
    from scenarios.pipeline import command, recording_cache

    scenario = scenarios.load(tiny[0] / "components" / "bench" / "scenario.toml")
    recording = recording_cache.get(scenario, "rosbag2", root=tiny[0].parent / "cache")
    assert recording.hit
    outputs = []
    for i in range(2):
        work = tmp_path / str(i)
        work.mkdir()
        env = {"kiss_icp_registration": '{"max_num_threads": 1}', "kiss_icp_data": '{"max_range": 10.0}', "kiss_icp_mapping": '{"voxel_size": 0.5}'}
        argv = [str(Path(sys.executable).parent / "kiss_icp_pipeline"), str(recording.path)]
        finished = command.run(argv, work, env, 120.0, work / "o.log", work / "e.log")
        assert finished.exit_code == 0, (work / "e.log").read_text()[-500:]
        (found,) = sorted(work.glob("results/latest/*_poses_tum.txt"))
        outputs.append(found.read_bytes())
    assert outputs[0] == outputs[1] and len(outputs[0].splitlines()) > 20


@pytest.mark.parametrize(
    "stack, args, needle",
    [
        (STACK, ["--findings", "g"], "--findings g: finding g cannot use a command component: its outlier shares are diagnostics"),
        (STACK, ["--findings", "a,e"], "--findings a: finding a cannot use a command component"),
        (STACK, ["--findings", "e,z"], "unknown finding 'z'"),
        (STACK.replace("kiss_icp_pipeline", "no_such_tool_riverbench"), [], "matchers.kiss.command: no_such_tool_riverbench: not found on PATH"),
        (
            STACK[STACK.index("[[estimators]]") :].replace(sys.executable, "/no/such/python"),
            [],
            "estimators.bag_truth.command: /no/such/python: no such",
        ),
        (STACK.replace('recording = "rosbag2"\noutput = "results', 'recording = "nmea"\noutput = "results'), [], "holds no scans"),
        ('name = "x"\nworld = "charles_river"\n', [], "no command component"),
        (STACK.replace('id = "kiss"', 'id = "gicp"'), [], "matchers.gicp: the study has a matcher of that id"),
        (None, ["--findings", "e"], "--findings: give --scenario FILE too"),
    ],
)
def test_bad_command_input_is_one_line_and_exit_2_before_anything_runs(tmp_path, stack, args, needle):
    if stack is not None:
        (tmp_path / "stack.toml").write_text(stack)
        args = [*args, "--scenario", str(tmp_path / "stack.toml")]
    out = tmp_path / "out"
    result = runner.invoke(app, ["study", "--out", str(out), "--workers", "1", "--quiet", *args])
    assert result.exit_code == 2, result.output
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1 and needle in lines[0] and "Traceback" not in result.output, result.output
    assert not out.exists()


def test_a_file_of_command_components_alone_is_enough(tmp_path):
    """Sections the file leaves out are empty, not the default stack (whose estimators ask for a gicp matcher)."""
    from scenarios.study.components import from_scenario

    kiss = STACK[STACK.index("[[matchers]]") : STACK.index("[[estimators]]")]
    (tmp_path / "kiss.toml").write_text(kiss)
    assert [(c.section, c.id, c.findings) for c in from_scenario(tmp_path / "kiss.toml", ("gicp",))] == [("matchers", "kiss", ("e", "f", "h"))]


def test_the_matching_causes_say_whether_the_lidar_tilts_between_revolutions(calm_and_chop):
    """tilt_change measures the angle between the LiDAR's vertical axes one revolution apart: exactly zero on glassy
    water, tenths of a degree in the basin's chop; the causes of f and g then name the chop instead of glassy water."""
    from scenarios.study.causes import cause
    from scenarios.study.matcher_findings import tilt_change

    calm, chop = calm_and_chop
    starts = np.linspace(5.0, 150.0, 40)
    assert tilt_change(calm, starts, 0.1) == {"median": 0.0, "p90": 0.0, "n": 40}
    tilted = tilt_change(chop, starts, 0.1)
    assert 0.02 < tilted["median"] < 1.0 and tilted["p90"] >= tilted["median"]
    f = {"band": (6000, 27000), "matchers": {"pcl6d": {"below_success": 0.25, "below_count": 200}}}
    assert "glassy water" in cause("f", "field", "partly", f, tilt_change(calm, starts, 0.1))
    assert "in the chop the LiDAR tilts" in cause("f", "field", "agrees", f, tilted)
    g = {"pcl6d": {"outlier_share": {"median": 0.26, "p90": 0.6, "n": 100}}}
    assert cause("g", "field", "disagrees", g, tilted).startswith("In the chop") and "26.0%" in cause("g", "field", "disagrees", g, tilted)
    assert cause("g", "bench", "agrees", g, None).startswith("Consecutive revolutions overlap")


@pytest.fixture(scope="module")
def calm_and_chop():
    from analytic_worlds import wall_world

    from sim.trajectory import Trajectory

    world = wall_world()
    return Trajectory(world, seed=4), Trajectory(world, seed=4, wind_waves={"wind_mps": 5.5, "fetch_m": 3000.0})
