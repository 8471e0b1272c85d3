"""`riverbench score`: a trajectory made outside the bench scored into a finished run directory as if its component had run
inside (scenarios.pipeline.rescore), under the contract it is declared with (scenarios.score.external, anchoring)."""

import hashlib
import json
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

import scenarios
from riverbench.unixtime import unix_ns
from scenarios.cli import app
from scenarios.pipeline import files
from sim.trajectory import mount_matrix

runner = CliRunner()
SHORT = [
    "stretch={start_s = 0.0, end_s = 20.0}",
    "gnss.forced_outages=[{start_s = 15.0, end_s = 17.0}]",  # a blackout and its re-acquisition: windows to pass through
    'expect=["estimators.ekf.ape.p95 < 50.0"]',
    'goals=["estimators.ext.ape.p95 < 50.0", "matchers.odo.ape_aligned.rmse < 0.01"]',
]
"""open_river for 20 s (200 scans, about 10 s to run on one core) with goals naming components it does not have."""


@pytest.fixture(scope="module")
def finished(tmp_path_factory) -> Path:
    """A finished run directory (no report: the scoring writes one) that each test copies before changing."""
    out = tmp_path_factory.mktemp("score") / "run"
    scenarios.run(scenarios.load("open_river", set=SHORT), out, workers=1, report=False)
    return out


@pytest.fixture
def run_dir(finished, tmp_path) -> Path:
    copy = tmp_path / "run"
    shutil.copytree(finished, copy)
    return copy


def score(run_dir: Path, component: str, *options: str):
    return runner.invoke(app, ["score", str(run_dir), component, *options, "--quiet", "--no-report"])


def metrics_of(run_dir: Path) -> dict:
    return json.loads((run_dir / "metrics.json").read_text())


def truth_of(run_dir: Path) -> tuple[np.ndarray, np.ndarray, int]:
    """groundtruth.tum's UNIX stamps (ns), its poses (N, 4, 4) and the run's time zero (UNIX ns)."""
    rows = files.read_tum(run_dir / "groundtruth.tum", scenario_time=True)
    poses = np.tile(np.eye(4), (len(rows), 1, 1))
    poses[:, :3, :3] = Rotation.from_quat(rows[:, 4:8]).as_matrix()
    poses[:, :3, 3] = rows[:, 1:4]
    zero = unix_ns(scenarios.load(run_dir / "scenario.toml").gnss.epoch_utc)
    return np.round(rows[:, 0] * 1e9).astype(np.int64) + zero, poses, zero


def write_tum(path: Path, stamps: list[str], poses: np.ndarray) -> Path:
    quaternion = Rotation.from_matrix(poses[:, :3, :3]).as_quat()
    lines = [f"{s} {p[0, 3]:.6f} {p[1, 3]:.6f} {p[2, 3]:.6f} {' '.join(f'{v:.9f}' for v in q)}" for s, p, q in zip(stamps, poses, quaternion)]
    path.write_text("# made outside\n" + "\n".join(lines) + "\n")
    return path


def unix_text(ns: np.ndarray) -> list[str]:
    return [f"{n // 10**9}.{n % 10**9:09d}" for n in ns]


def test_an_estimators_own_tum_file_scored_back_gives_its_numbers(run_dir):
    result = score(run_dir, f"ekf_again={run_dir / 'ekf.tum'}")
    assert result.exit_code == 0, result.output
    tree = metrics_of(run_dir)
    built_in, again = tree["estimators"]["ekf"], tree["estimators"]["ekf_again"]
    for key in ("rmse", "mean", "median", "p95", "max"):
        assert again["ape"][key] == pytest.approx(built_in["ape"][key], abs=1e-6), key
    for family in ("rpe_10m", "yaw"):
        assert again[family]["rmse"] == pytest.approx(built_in[family]["rmse"], abs=1e-6)
    assert again["windows"]["blackout"]["count"] == 1 and again["windows"] == built_in["windows"]
    assert again["coverage"] == again["available"] == built_in["available"]
    assert again["source"]["anchor"] == "map" and again["source"]["poses"] == len(files.read_tum(run_dir / "ekf.tum"))
    columns = (run_dir / "windows.csv").read_text().splitlines()
    header, row = columns[0].split(","), columns[1].split(",")
    assert row[header.index("ekf_again.max_error")] == row[header.index("ekf.max_error")] != ""
    assert np.allclose(files.read_tum(run_dir / "ekf_again.tum"), files.read_tum(run_dir / "ekf.tum"))


def test_se3_anchor_agrees_with_evo_ape_aligned(run_dir, tmp_path):
    from evo.core import metrics, sync
    from evo.tools import file_interface

    stamps, truth, _ = truth_of(run_dir)
    rng = np.random.default_rng(0)
    noisy = truth.copy()
    noisy[:, :2, 3] += rng.normal(0.0, 0.3, (len(truth), 2))
    tilt = np.eye(4)
    tilt[:3, :3] = Rotation.from_euler("xyz", [3.0, -2.0, 70.0], degrees=True).as_matrix()
    tilt[:3, 3] = [120.0, -40.0, 5.0]
    keep = np.arange(len(truth)) % 7 != 3  # dropped frames
    est = write_tum(tmp_path / "est.tum", unix_text(stamps[keep]), (tilt @ noisy)[keep])
    result = score(run_dir, f"odo={est}", "--anchor", "se3")
    assert result.exit_code == 0, result.output
    node = metrics_of(run_dir)["matchers"]["odo"]
    assert node["coverage"] == pytest.approx(keep.mean(), abs=1e-4)

    reference, estimate = sync.associate_trajectories(
        file_interface.read_tum_trajectory_file(str(run_dir / "groundtruth.tum")), file_interface.read_tum_trajectory_file(str(est))
    )
    estimate.align(reference)
    ape = metrics.APE(metrics.PoseRelation.translation_part)
    ape.process_data((reference, estimate))
    assert node["ape"]["rmse"] == pytest.approx(ape.get_statistic(metrics.StatisticsType.rmse), abs=1e-3)


def test_lidar_odometry_from_identity_in_kitti_layout_is_laid_onto_the_truth(run_dir, tmp_path):
    stamps, truth, _ = truth_of(run_dir)
    mount = mount_matrix(scenarios.load(run_dir / "scenario.toml").vessel)
    lidar = truth @ mount
    odometry = np.linalg.inv(lidar[5]) @ lidar[5:]  # what KISS-ICP writes: the LiDAR's poses from identity at its first scan
    (tmp_path / "poses.txt").write_text("\n".join(" ".join(f"{v:.9f}" for v in p[:3].ravel()) for p in odometry) + "\n")
    (tmp_path / "times.txt").write_text("\n".join(f"{(s - stamps[0]) / 1e9:.6f}" for s in stamps[5:]) + "\n")
    contract = ["--format", "kitti", "--times", str(tmp_path / "times.txt"), "--frame", "lidar", "--clock", "first_scan", "--anchor", "first"]
    result = score(run_dir, f"odo={tmp_path / 'poses.txt'}", *contract)
    assert result.exit_code == 0, result.output
    node = metrics_of(run_dir)["matchers"]["odo"]
    assert node["ape"]["max"] < 1e-3 and node["yaw"]["max"] < 1e-3
    assert node["coverage"] == pytest.approx(1.0 - 5 / len(truth), abs=1e-4)
    assert node["source"]["format"] == "kitti" and node["source"]["frame"] == "lidar"


def test_a_goal_naming_the_scored_component_is_judged_and_the_report_shows_it(run_dir):
    before = metrics_of(run_dir)
    assert {g["goal"]: g for g in before["goals"]}["estimators.ext.ape.p95 < 50"]["met"] is None  # no such component yet
    result = runner.invoke(app, ["score", str(run_dir), f"ext={run_dir / 'gps_only.tum'}", "--quiet"])
    assert result.exit_code == 0, result.output
    tree = metrics_of(run_dir)
    goal = {g["goal"]: g for g in tree["goals"]}["estimators.ext.ape.p95 < 50"]
    assert goal["met"] is True and goal["value"] == tree["estimators"]["ext"]["ape"]["p95"]
    assert tree["expectations"] == before["expectations"] and all(e["pass"] for e in tree["expectations"])
    report = (run_dir / "report.md").read_text()
    assert "Scored in afterwards" in report and "gps_only.tum" in report and "| ext" in report
    assert (run_dir / "plots" / "map.png").is_file() and (run_dir / "ext.tum").is_file()
    again = runner.invoke(app, ["score", str(run_dir), f"ext={run_dir / 'ekf.tum'}", "--quiet", "--no-report", "--replace"])
    assert again.exit_code == 0, again.output
    assert metrics_of(run_dir)["estimators"]["ext"]["source"]["file"].endswith("ekf.tum")


def test_a_missed_goal_of_the_scored_odometry_is_reported_not_met(run_dir):
    result = score(run_dir, f"odo={run_dir / 'gps_only.tum'}", "--anchor", "se2")
    assert result.exit_code == 0, result.output
    goal = {g["goal"]: g for g in metrics_of(run_dir)["goals"]}["matchers.odo.ape_aligned.rmse < 0.01"]
    assert goal["met"] is False and goal["value"] > 0.01


def bad_tum(run_dir: Path, tmp_path: Path, case: str) -> tuple[list[str], str]:
    """The files and options of one bad input, and what its one line must say."""
    stamps, truth, zero = truth_of(run_dir)
    good = unix_text(stamps)
    path = tmp_path / "bad.tum"
    shifted = lambda seconds: write_tum(path, unix_text(stamps + seconds * 10**9), truth)
    if case == "missing":
        return [f"x={tmp_path / 'nothing.tum'}"], "no such file"
    if case == "unreadable":
        path.write_bytes(b"\xff\xfe\x00garbage")
        return [f"x={path}"], "cannot read"
    if case == "directory":
        return [f"x={tmp_path}"], "cannot read"
    if case == "seven numbers":
        write_tum(path, good, truth)
        lines = path.read_text().splitlines()
        lines[4] = " ".join(lines[4].split()[:7])
        path.write_text("\n".join(lines) + "\n")
        return [f"x={path}"], "line 5: 7 fields, not 8 numbers"
    if case == "a word":
        write_tum(path, good, truth)
        path.write_text(path.read_text() + "end of file\n")
        return [f"x={path}"], "not 8 numbers"
    if case in ("nan", "inf"):
        write_tum(path, good, truth)
        lines = path.read_text().splitlines()
        fields = lines[10].split()
        fields[2] = case
        lines[10] = " ".join(fields)
        path.write_text("\n".join(lines) + "\n")
        return [f"x={path}"], "line 11: " + case + " is not a finite number"
    if case == "repeated stamp":
        write_tum(path, good[:20] + [good[19]] + good[21:], truth)
        return [f"x={path}"], "line 22: stamp"
    if case == "outside":
        shifted(500)
        return [f"x={path}"], "lie outside the run"
    if case == "an hour late":
        shifted(3600)
        return [f"x={path}"], "3600 s late (1 h off: a time-zone offset?"
    if case == "leap seconds":
        shifted(18)
        return [f"x={path}"], "18 s late (GPS time, not UTC"
    if case == "unix as run":
        write_tum(path, good, truth)
        return [f"x={path}", "--clock", "run"], "the stamps are UNIX time, not seconds on the run's clock (--clock run): declare --clock unix"
    if case == "run as unix":
        write_tum(path, [f"{(s - zero) / 1e9:.6f}" for s in stamps], truth)
        return [f"x={path}"], "the stamps are seconds on the run's clock, not UNIX time (--clock unix): declare --clock run"
    kitti = tmp_path / "poses.txt"
    kitti.write_text("\n".join(" ".join(f"{v:.6f}" for v in p[:3].ravel()) for p in truth) + "\n")
    times = tmp_path / "times.txt"
    if case == "kitti without times":
        return [f"x={kitti}", "--format", "kitti"], "--format kitti: give --times FILE"
    if case == "kitti times short":
        times.write_text("\n".join(f"{(s - zero) / 1e9:.6f}" for s in stamps[:-1]) + "\n")
        return [f"x={kitti}", "--format", "kitti", "--times", str(times), "--clock", "run"], f"has {len(stamps) - 1} stamps but"
    if case == "kitti thirteen numbers":
        times.write_text("\n".join(f"{(s - zero) / 1e9:.6f}" for s in stamps) + "\n")
        kitti.write_text(kitti.read_text().replace("\n", " 1\n", 1))
        return [f"x={kitti}", "--format", "kitti", "--times", str(times), "--clock", "run"], "line 1: 13 fields, not 12 numbers"
    if case == "built-in name":
        return [f"ekf={run_dir / 'ekf.tum'}"], "the run already has an estimator 'ekf', built in"
    if case == "bad name":
        return [f"2fast={run_dir / 'ekf.tum'}"], "NAME '2fast': not a component id"
    if case == "no name":
        return [str(run_dir / "ekf.tum")], "give NAME=FILE"
    if case == "bad anchor":
        return [f"x={run_dir / 'ekf.tum'}", "--anchor", "gps"], "--anchor gps: use map, first, se2, se3"
    raise AssertionError(case)


BAD = [
    "missing",
    "unreadable",
    "directory",
    "seven numbers",
    "a word",
    "nan",
    "inf",
    "repeated stamp",
    "outside",
    "an hour late",
    "leap seconds",
    "unix as run",
    "run as unix",
    "kitti without times",
    "kitti times short",
    "kitti thirteen numbers",
    "built-in name",
    "bad name",
    "no name",
    "bad anchor",
]


def digest(directory: Path) -> dict[str, str]:
    return {str(p.relative_to(directory)): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(directory.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("case", BAD)
def test_bad_input_is_one_line_on_stderr_exit_2_and_nothing_changed(run_dir, tmp_path, case):
    inputs = tmp_path / "inputs"
    inputs.mkdir()
    args, needle = bad_tum(run_dir, inputs, case)
    before = digest(run_dir)
    result = runner.invoke(app, ["score", str(run_dir), *args, "--quiet"])
    assert result.exit_code == 2, result.output
    assert result.stdout == "" and len(result.stderr.strip().splitlines()) == 1, result.output
    assert needle in result.stderr and "Traceback" not in result.stderr, result.stderr
    assert digest(run_dir) == before
    assert sorted(p.name for p in run_dir.parent.iterdir()) == ["inputs", "run"]  # no staged copy left behind


def test_a_scored_in_name_needs_replace_and_a_replay_has_no_truth(run_dir, tmp_path):
    assert score(run_dir, f"ext={run_dir / 'gps_only.tum'}").exit_code == 0
    before = digest(run_dir)
    again = score(run_dir, f"ext={run_dir / 'pf.tum'}")
    assert again.exit_code == 2 and "scored from" in again.stderr and "--replace" in again.stderr
    assert digest(run_dir) == before
    (run_dir / "groundtruth.tum").unlink()
    replayed = score(run_dir, f"other={run_dir / 'pf.tum'}")
    assert replayed.exit_code == 2 and "no groundtruth.tum" in replayed.stderr


def test_an_interrupted_score_leaves_the_run_as_it_was(run_dir, monkeypatch):
    from scenarios.pipeline import rescore

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(rescore, "rewrite_windows_csv", interrupted)
    before = digest(run_dir)
    result = score(run_dir, f"ext={run_dir / 'gps_only.tum'}")
    assert result.exit_code == 130 and "left as it was" in result.stderr
    assert digest(run_dir) == before and sorted(p.name for p in run_dir.parent.iterdir()) == ["run"]
    assert not math.isnan(metrics_of(run_dir)["estimators"]["ekf"]["ape"]["rmse"])


def test_align_se3_undoes_a_rigid_motion_and_keeps_missing_poses_missing():
    from scenarios.score.metrics import align_se3

    rng = np.random.default_rng(3)
    truth = np.tile(np.eye(4), (40, 1, 1))
    truth[:, :3, 3] = np.c_[np.cumsum(rng.uniform(0.5, 1.5, 40)), rng.normal(0.0, 4.0, 40), np.zeros(40)]
    motion = np.eye(4)
    motion[:3, :3] = Rotation.from_euler("xyz", rng.uniform(-40.0, 40.0, 3), degrees=True).as_matrix()
    motion[:3, 3] = rng.normal(0.0, 50.0, 3)
    moved = motion @ truth
    moved[7] = np.nan
    aligned = align_se3(moved, truth)
    assert np.isnan(aligned[7]).all()
    assert np.allclose(np.delete(aligned, 7, axis=0), np.delete(truth, 7, axis=0), atol=1e-9)
