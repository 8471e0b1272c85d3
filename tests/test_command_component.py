"""Matchers and estimators of `kind = "command"` (scenarios.spec.command, scenarios.pipeline.external): an executable run on
the scenario's cached recording, its trajectory read back under the score contract and scored like a built-in; a
command that fails is a failed component with its reason, and the rest of the run is as without it."""

import json
import shutil
import signal
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import scenarios
from scenarios.batch.plan import Axis, SweepPlan
from scenarios.cli import app
from scenarios.pipeline import command, recording_cache
from scenarios.pipeline.runner import RunResult

runner = CliRunner()
BUILT_INS = [
    "stretch={start_s = 0.0, end_s = 5.0}",
    'matchers=[{id = "bev", kind = "bev3dof"}]',
    'estimators=[{id = "gps_only", kind = "gps_only"}]',
    "expect=[]",
    "goals=[]",
]
"""open_river for 5 s (50 scans) with a cheap matcher and estimator beside the commands."""

FAKE = textwrap.dedent(
    '''
    """Fake odometry: the KITTI recording's true LiDAR poses as a TUM file on the first-scan clock, `shift` s late."""
    import os, sys
    from pathlib import Path
    import numpy as np

    recording, out, shift = Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3])
    print("step", os.environ.get("RIVERBENCH_PARAM_STEP"))
    tr = np.array([[0.0, -1, 0, 0], [0, 0, -1, 0], [1, 0, 0, 0], [0, 0, 0, 1]])
    rows = np.loadtxt(recording / "poses" / "00.txt", ndmin=2)
    times = np.loadtxt(recording / "sequences" / "00" / "times.txt", ndmin=1)
    poses = np.tile(np.eye(4), (len(rows), 1, 1))
    poses[:, :3, :] = rows.reshape(-1, 3, 4)
    poses = np.linalg.inv(tr) @ poses @ tr
    every = int(sys.argv[4])  # a pose every `every` scans
    with open(out / "poses_tum.txt", "w") as f:
        for t, p in zip(times[::every], poses[::every]):
            w = np.sqrt(max(0.0, 1 + np.trace(p[:3, :3]))) / 2  # the fixtures' poses turn less than 180 deg
            q = [(p[2, 1] - p[1, 2]) / (4 * w), (p[0, 2] - p[2, 0]) / (4 * w), (p[1, 0] - p[0, 1]) / (4 * w), w]
            f.write(f"{t + shift:.6f} {p[0, 3]:.9f} {p[1, 3]:.9f} {p[2, 3]:.9f} {' '.join(f'{v:.12f}' for v in q)}\\n")
    '''
)


def fake(cid: str, script: Path = Path("fake.py"), shift: float = 0.0, step: int = 1, anchor: str = "first") -> str:
    """A --set of one fake odometry command component running `script`."""
    return (
        f'{{id = "{cid}", kind = "command", command = "{sys.executable} {script} {{recording}} {{out}} {shift} {{step}}", '
        f'recording = "kitti", output = "out/poses_tum.txt", frame = "lidar", clock = "first_scan", anchor = "{anchor}", '
        f"timeout_s = 60, params = {{step = {step}}}}}"
    )


EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
BAG_TRUTH = (
    f'{{id = "bag_truth", kind = "command", command = "{sys.executable} {EXAMPLES}/ros2/odometry_to_tum.py {{recording}} '
    '/ground_truth/odom {out}/truth.tum", recording = "rosbag2", output = "out/truth.tum", anchor = "map", timeout_s = 60}'
)
"""The ROS 2 wrapper's converter run on the rosbag2 recording's own truth topic: an estimator exact by construction."""


def bad(cid: str, command: str, **more: str) -> str:
    fields = {"output": '"out/poses_tum.txt"', "recording": '"kitti"', "timeout_s": "60"} | more
    return f'{{id = "{cid}", kind = "command", command = {json.dumps(command)}, ' + ", ".join(f"{k} = {v}" for k, v in fields.items()) + "}"


def with_commands(matchers: list[str], estimators: list[str] = ()) -> list[str]:
    return [
        "stretch={start_s = 0.0, end_s = 5.0}",
        f'matchers=[{{id = "bev", kind = "bev3dof"}}, {", ".join(matchers)}]',
        f'estimators=[{{id = "gps_only", kind = "gps_only"}}{"".join(", " + e for e in estimators)}]',
        "expect=[]",
        "goals=[]",
    ]


EXPECT = [
    "matchers.odo.ape.rmse < 0.001",
    "matchers.silent.ape_aligned.rmse < 1000",
    "estimators.gps_only.ape.p95 < 1000",
    "matchers.exits3.external.wall_s < 1000",
    "estimators.gps_only.ape.p95 < matchers.tenth.ape.p95 + 1000",
]


def run(tmp: Path, name: str, assignments: list[str], expect: list[str] = ()) -> RunResult:
    scenario = scenarios.load("open_river", set=[*assignments, f"expect={json.dumps(list(expect))}"])
    return scenarios.run(scenario, tmp / name, workers=1, report=name == "bad")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Three runs sharing a recording cache: `bad` (a good fake matcher and estimator beside five failing commands),
    `other` (the fake at another parameter: the recording comes from the cache) and `plain` (no command at all)."""
    tmp = tmp_path_factory.mktemp("commands")
    script = tmp / "fake.py"
    script.write_text(FAKE)
    failing = [
        bad("exits3", "sh -c 'echo it broke >&2; exit 3'"),
        bad("sleeps", "sleep 30", timeout_s="1"),
        bad("silent", "true"),
        bad("garbage", "sh -c 'echo not a pose > out/poses_tum.txt'"),
        fake("late", script, shift=3600.0),
        fake("tenth", script, step=10),
    ]
    plan = {
        "bad": (with_commands([fake("odo", script), *failing], [fake("fused", script)]), EXPECT),
        "other": (with_commands([fake("odo", script, step=2)], [BAG_TRUTH]), ()),
        "plain": (BUILT_INS, ()),
    }
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("RIVERBENCH_CACHE", str(tmp / "cache"))
        yield {name: run(tmp, name, sets, expect) for name, (sets, expect) in plan.items()}


def node(result, section: str, cid: str) -> dict:
    return result.metrics[section][cid]


def test_a_fake_command_is_scored_exactly_as_a_matcher_and_an_estimator(runs):
    odo, fused = node(runs["bad"], "matchers", "odo"), node(runs["bad"], "estimators", "fused")
    assert odo["failed"] is False and fused["failed"] is False
    assert odo["ape"]["rmse"] == pytest.approx(0.0, abs=1e-4) and odo["yaw"]["max"] == pytest.approx(0.0, abs=1e-3)
    assert fused["ape"]["p95"] == pytest.approx(0.0, abs=1e-4) and fused["available"] == 1.0
    assert odo["coverage"] == 1.0 and odo["external"]["poses"] == runs["bad"].metrics["run"]["scans"]
    ext = odo["external"]
    assert ext["exit_code"] == 0 and ext["wall_s"] > 0 and ext["cpu_s"] > 0 and ext["peak_rss_mb"] > 1
    out = runs["bad"].out_dir
    assert (out / "odo.tum").is_file() and (out / "fused.tum").is_file()
    assert any(column.startswith("fused.") for column in (out / "windows.csv").read_text().splitlines()[0].split(","))
    assert (out / "commands" / "odo.stdout.log").read_text().strip() == "step 1"
    report = (out / "report.md").read_text()
    assert "## Command components" in report and "| odo | matcher | ok |" in report


@pytest.mark.parametrize(
    "cid, reason",
    [
        ("exits3", "the command exited with code 3; its stderr ends: it broke"),
        ("sleeps", "timed out after 1 s (timeout_s) and was ended"),
        ("silent", "the command wrote no file matching output = 'out/poses_tum.txt' in its working folder"),
        ("garbage", "line 1: 3 fields, not 8 numbers"),
        ("late", "3600 s late (1 h off: a time-zone offset? UNIX time is UTC)"),
        ("tenth", "5 poses cover 10.0% of the run's 50 scans, below min_coverage 50%"),
    ],
)
def test_a_bad_command_is_a_failed_component_with_its_reason(runs, cid, reason):
    result = runs["bad"]
    n = node(result, "matchers", cid)
    assert n["failed"] is True and reason in n["reason"] and "\n" not in n["reason"]
    assert "ape" not in n and not (result.out_dir / f"{cid}.tum").exists()
    assert {"component": "matcher", "id": cid, "stamp": None, "reason": n["reason"]} in result.metrics["run"]["failures"]
    assert f"| {cid} | matcher | **failed: " in (result.out_dir / "report.md").read_text()


def test_a_failed_command_fails_its_expectations_and_nothing_else(runs):
    outcomes = {o["expect"]: o["pass"] for o in runs["bad"].metrics["expectations"]}
    assert outcomes == dict(zip(EXPECT, (True, False, True, False, False)))
    assert not runs["bad"].passed
    reasons = [o["reason"] for o in runs["bad"].metrics["expectations"]]
    assert reasons[1] == "matchers.silent failed: the command wrote no file matching output = 'out/poses_tum.txt' in its working folder"
    assert reasons[3].startswith("matchers.exits3 failed: the command exited with code 3")  # its costs pass no check either
    assert reasons[4].startswith("matchers.tenth failed: ") and "below min_coverage" in reasons[4]


def test_the_ros2_examples_converter_reads_a_rosbag2_recording_back_exactly(runs):
    n = node(runs["other"], "estimators", "bag_truth")
    assert n["failed"] is False, n.get("reason")
    assert n["ape"]["max"] == 0.0 and n["yaw"]["max"] == 0.0 and n["coverage"] == 1.0 and n["available"] == 1.0
    assert n["external"]["recording"] == "rosbag2" and n["external"]["recording_cached"] is False


def test_the_built_ins_are_as_in_a_run_without_commands(runs):
    for section, cid in (("matchers", "bev"), ("estimators", "gps_only")):
        assert json.dumps(node(runs["bad"], section, cid)) == json.dumps(node(runs["plain"], section, cid))
    for name in ("gps_only.tum", "bev.tum", "groundtruth.tum", "gps.csv"):
        assert (runs["bad"].out_dir / name).read_bytes() == (runs["plain"].out_dir / name).read_bytes()


def test_the_recording_is_written_once_and_reused(runs):
    first, again = node(runs["bad"], "matchers", "odo")["external"], node(runs["other"], "matchers", "odo")["external"]
    assert first["recording_cached"] is False and again["recording_cached"] is True
    assert again["recording_s"] < first["recording_s"]
    assert (runs["other"].out_dir / "commands" / "odo.stdout.log").read_text().strip() == "step 2"
    assert node(runs["other"], "matchers", "odo")["ape"] == node(runs["bad"], "matchers", "odo")["ape"]
    assert node(runs["other"], "matchers", "odo")["coverage"] == 0.5 and node(runs["bad"], "matchers", "odo")["coverage"] == 1.0


def test_bad_command_fields_are_one_line_before_anything_runs(tmp_path):
    def invoke(matcher: str, out: Path):
        sets = [*BUILT_INS[1:], f"matchers=[{matcher}]"]
        return runner.invoke(app, ["run", "open_river", "--out", str(out), "--quiet", *[a for s in sets for a in ("--set", s)]])

    cases = {
        "x {bogus}": "matchers.ext: command: unknown placeholder {bogus}",
        "no_such_tool_riverbench {recording}": "matchers.ext.command: no_such_tool_riverbench: not found on PATH",
    }
    for line, message in cases.items():
        out = tmp_path / "never"
        result = invoke(bad("ext", line), out)
        assert result.exit_code == 2 and message in result.output and not out.exists(), result.output
    for field, value, message in (("recording", '"bag"', "matchers.ext: recording:"), ("anchor", '"se4"', "matchers.ext: anchor:")):
        result = invoke(bad("ext", "true", **{field: value}), tmp_path / "never")
        assert result.exit_code == 2 and message in result.output, result.output


def test_the_cache_key_ignores_what_cannot_change_the_recording():
    base = scenarios.load("open_river", set=BUILT_INS)
    other = scenarios.load("open_river", set=[*with_commands([fake("odo", step=7)]), 'expect=["estimators.gps_only.ape.p95 < 9"]'])
    assert recording_cache.key(base, "kitti") == recording_cache.key(other, "kitti")
    assert recording_cache.key(base, "kitti") != recording_cache.key(base, "rosbag2")
    assert recording_cache.key(base, "kitti") != recording_cache.key(scenarios.load("open_river", set=[*BUILT_INS, "seed=1"]), "kitti")


def test_a_resolved_scenario_keeps_its_commands_where_they_were_written():
    scenario = scenarios.load("open_river", set=with_commands([fake("odo")], [fake("fused")]))
    data = scenario.resolved()
    assert [m["id"] for m in data["matchers"]] == ["bev", "odo"] and [e["id"] for e in data["estimators"]] == ["gps_only", "fused"]
    again = type(scenario).model_validate(data)
    assert again.hash == scenario.hash and [c.id for _, c in again.commands] == ["odo", "fused"]
    assert "command" not in json.dumps(scenarios.load("open_river", set=BUILT_INS).resolved())


def test_an_interrupt_of_the_bench_ends_the_commands_whole_group(tmp_path):
    def interrupt(*_):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGALRM, interrupt)
    signal.setitimer(signal.ITIMER_REAL, 0.5)
    try:
        with pytest.raises(KeyboardInterrupt):
            command.run(["sh", "-c", "sleep 30 & echo $! > child.pid; wait"], tmp_path, {}, 60.0, tmp_path / "o.log", tmp_path / "e.log")
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    child = Path(f"/proc/{(tmp_path / 'child.pid').read_text().strip()}/status")
    deadline = time.monotonic() + 5
    while child.exists() and "\tZ" not in child.read_text() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not child.exists() or "State:\tZ" in child.read_text()  # gone, or a zombie waiting for its new parent


def _evo_ape(reference: Path, estimate: Path) -> float:
    """evo_ape tum REFERENCE ESTIMATE -a --project_to_plane xy: the SE(3) fit, then the error in the plane (the bench's
    APE is horizontal; without the projection evo adds the LiDAR's heave and the fit's tilt, 19 mm on quickstart)."""
    from evo.core import metrics, sync
    from evo.core.trajectory import Plane
    from evo.tools import file_interface

    ref, est = file_interface.read_tum_trajectory_file(reference), file_interface.read_tum_trajectory_file(estimate)
    ref, est = sync.associate_trajectories(ref, est, max_diff=0.025)
    est.align(ref, correct_scale=False)
    ref.project(Plane.XY)
    est.project(Plane.XY)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((ref, est))
    return float(ape.get_statistic(metrics.StatisticsType.rmse))


@pytest.mark.slow
def test_kiss_icp_pipeline_as_a_command_matcher_scores_as_evo_does(tmp_path, monkeypatch):
    """kiss_icp_pipeline on a rosbag2 recording of 30 m of canal_multipath (about 50 s on 2 loaded cores): its APE after
    the declared se3 anchor equals evo_ape -a on the same files to 1 mm."""
    if shutil.which("kiss_icp_pipeline") is None:
        monkeypatch.setenv("PATH", f"{Path(sys.executable).parent}:{__import__('os').environ['PATH']}")
    monkeypatch.setenv("RIVERBENCH_CACHE", str(tmp_path / "cache"))
    kiss = (
        '{id = "kiss", kind = "command", '
        "command = '''env 'kiss_icp_registration={{\"max_num_threads\": 1}}' 'kiss_icp_data={{\"max_range\": {max_range}}}' "
        "'kiss_icp_mapping={{\"voxel_size\": {voxel_size}}}' "
        "kiss_icp_pipeline {recording}''', "
        'recording = "rosbag2", output = "results/**/*_poses_tum.txt", anchor = "se3", timeout_s = 600, '
        "params = {max_range = 100.0, voxel_size = 0.5}}"
    )
    sets = ["stretch={start_m = 350.0, end_m = 380.0}", f"matchers=[{kiss}]", *BUILT_INS[2:]]
    result = scenarios.run(scenarios.load("canal_multipath", set=sets), tmp_path / "run", workers=1, report=False)
    n = result.metrics["matchers"]["kiss"]
    assert n["failed"] is False, n.get("reason")
    assert n["coverage"] > 0.95 and n["ape"]["rmse"] < 0.5
    evo = _evo_ape(result.out_dir / "groundtruth.tum", result.out_dir / n["external"]["output"])
    assert abs(n["ape"]["rmse"] - evo) < 1e-3
    assert np.isfinite(n["rpe_10m"]["mean"])


def test_a_sweeps_objective_and_plots_take_a_command_components_metrics(runs, tmp_path):
    """The fixture's runs with the fake odometry at step 1 (`bad`) and 2 (`other`) as the rows of a sweep over the step."""
    from scenarios.batch import sweep as sweeping
    from scenarios.batch import table

    plan = SweepPlan(("open_river",), grid=(Axis.parse("matchers.odo.params.step=1,2"),), fixed=tuple(with_commands([fake("odo")])))
    objective = "matchers.odo.coverage"
    for metric in (objective, "matchers.odo.ape_aligned.rmse", "matchers.odo.external.wall_s"):
        sweeping.check_metric(metric, plan.points())
    with pytest.raises(ValueError, match=r"'matchers.odo.covered': no such metric.*e\.g\. matchers\.odo\.ape\.max"):
        sweeping.check_metric("matchers.odo.covered", plan.points())
    rows = [table.row(p, "ok", 1.0, name, runs[name].metrics) for p, name in zip(plan.points(), ("bad", "other"))]
    assert [(r.params, r.median) for r in sweeping.rank(rows, objective, minimize=False)] == [
        ({"matchers.odo.params.step": 1}, 1.0),
        ({"matchers.odo.params.step": 2}, 0.5),
    ]
    result = sweeping.SweepResult(tmp_path, rows, 2, 0)
    assert [p.name for p in sweeping.write_plots(result, plan, objective, [])] == ["matchers.odo.coverage--matchers.odo.params.step.png"]
    default = {p.name for p in sweeping.write_plots(result, plan, None, [])}
    assert default == {f"{m}--matchers.odo.params.step.png" for m in ("estimators.all.ape.p95", "matchers.bev.success", objective)}


def test_a_baseline_flags_a_crippled_command_as_regressed(runs):
    """The fixture's fake odometry at step 1 (`bad`) as the baseline, at step 2 (`other`, a pose every second scan) now:
    its coverage regresses and fails the comparison (suite --baseline's exit 1); its costs are wall-clock figures."""
    from scenarios.score import baseline, regression

    def measured(name: str) -> baseline.Baseline:
        result = runs[name]
        return baseline.from_runs({"open_river": [(0, "h", result.metrics, "")]}, fast=False, overrides=[], provenance={})

    comparison = regression.compare(measured("bad"), measured("other"))
    verdicts = {v.metric: v for v in comparison.verdicts}
    assert [v.metric for v in comparison.regressions] == ["matchers.odo.coverage"] and comparison.failed
    assert verdicts["matchers.odo.ape.rmse"].verdict == "unchanged" and verdicts["matchers.bev.ape.rmse"].identical
    assert all(verdicts[f"matchers.odo.external.{k}"].family.wall_clock for k in ("wall_s", "cpu_s", "peak_rss_mb", "recording_s"))
    assert verdicts["matchers.odo.external.recording_cached"].verdict == "changed"
