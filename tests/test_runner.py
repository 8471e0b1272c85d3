"""The runner: the run directory's files against the simulator's truth, determinism across worker
counts and re-runs of the resolved scenario, recorded failures, and nothing half-written on disk."""

import calendar
import csv
import json
import os
import subprocess
import sys
import tomllib
from functools import reduce
from pathlib import Path

import numpy as np
import pynmea2
import pytest

import scenarios
import sim
import worlds
from scenarios.pipeline import files
from scenarios.pipeline.feed import LOOKAHEAD_SCANS, PIPELINED_SCANS
from scenarios.pipeline.runner import RunFailed, RunInterrupted
from scenarios.pipeline.scan_ahead import ScanAhead
from scenarios.spec.library import validate

SHORT = ["stretch={start_s = 60.0, end_s = 90.0}"]  # canal_lock: walls on both sides, 30 s


def short(name="rough_water", extra=()):
    return scenarios.load(name, set=[*SHORT, *extra])


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("runs") / "short"
    return scenarios.run(short(), out, workers=2, report=False)


def test_run_directory_holds_every_file(short_run):
    names = {p.name for p in short_run.out_dir.iterdir()}
    expected = {"scenario.toml", "metrics.json", "groundtruth.tum", "gps.csv", "gps.nmea", "windows.csv", "scans.csv"}
    expected |= {f"{e.id}.tum" for e in short_run.scenario.estimators} | {f"{m.id}.tum" for m in short_run.scenario.matchers}
    assert expected <= names
    assert not [p for p in short_run.out_dir.parent.iterdir() if p.name.startswith(".")]


def test_groundtruth_is_the_trajectory_at_scan_times(short_run):
    """At the waterline: the true plane position and attitude, z = 0 (not rough water's heave)."""
    s = short_run.scenario
    trajectory = sim.Trajectory(worlds.load(s.world, **s.world_params), seed=s.seed, **s.vessel.model_dump(exclude={"seed"}))
    rows = files.read_tum(short_run.out_dir / "groundtruth.tum", scenario_time=True)
    assert len(rows) == 300 and np.allclose(np.diff(rows[:, 0]), 0.1)
    poses = trajectory.poses(rows[:, 0])
    assert np.abs(poses[:, 2, 3]).max() > 0.05  # rough water heaves the hull...
    assert np.allclose(rows[:, 1:3], poses[:, :2, 3], atol=2e-6) and not rows[:, 3].any()  # ...the file keeps the waterline
    from scipy.spatial.transform import Rotation

    assert np.allclose(Rotation.from_quat(rows[:, 4:]).as_matrix(), poses[:, :3, :3], atol=1e-6)
    assert np.allclose(np.linalg.norm(rows[:, 4:], axis=1), 1.0)


def test_tum_stamps_are_unix_time_from_the_gnss_epoch_and_the_stretch_start(short_run):
    """UNIX seconds of `[gnss] epoch_utc` (UTC, no leap seconds: calendar.timegm, not GPS time) + the scan's time."""
    epoch = short_run.scenario.gnss.epoch_utc
    unix_epoch = calendar.timegm(epoch.utctimetuple()) + epoch.microsecond / 1e6
    assert epoch.utcoffset().total_seconds() == 0 and unix_epoch == 1_532_876_400.0  # the default epoch: 2018-07-29T15:00:00Z
    t_start = short_run.metrics["run"]["t_start"]
    assert t_start == pytest.approx(60.0, abs=0.1)  # the stretch starts at 60 s of the trajectory
    for name in ("groundtruth.tum", "ekf.tum", "gicp.tum"):
        path = short_run.out_dir / name
        first = path.read_text().splitlines()[2].split()[0]
        assert len(first.split(".")[1]) == 9  # nanoseconds
        rows, on_clock = files.read_tum(path), files.read_tum(path, scenario_time=True)
        assert rows[:, 0] == pytest.approx(unix_epoch + on_clock[:, 0], abs=1e-6)
    truth = files.read_tum(short_run.out_dir / "groundtruth.tum")
    assert truth[0, 0] == pytest.approx(unix_epoch + t_start, abs=1e-6)
    # the first GGA's UTC time of day (pynmea2 reads it) is the same instant: a fix shares the first scan's stamp
    gga = next(pynmea2.parse(line) for line in (short_run.out_dir / "gps.nmea").read_text().splitlines() if "GGA" in line)
    seconds_of_day = gga.timestamp.hour * 3600 + gga.timestamp.minute * 60 + gga.timestamp.second + gga.timestamp.microsecond / 1e6
    assert seconds_of_day == pytest.approx(truth[0, 0] % 86400, abs=0.01)


def test_evo_on_the_run_files_gives_the_bench_ape(short_run):
    """evo (its default APE: 3-D translation, no --project_to_plane, no alignment) on groundtruth.tum and an
    estimator's or matcher's file reproduces metrics.json's horizontal APE to 1 mm: the files sit at the waterline."""
    from evo.core import metrics as evo_metrics
    from evo.core import sync
    from evo.tools import file_interface

    m = short_run.metrics
    for kind, cid in (("estimators", "ekf"), ("estimators", "gps_only"), ("matchers", "gicp")):
        reference = file_interface.read_tum_trajectory_file(str(short_run.out_dir / "groundtruth.tum"))
        estimate = file_interface.read_tum_trajectory_file(str(short_run.out_dir / f"{cid}.tum"))
        reference, estimate = sync.associate_trajectories(reference, estimate)
        ape = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
        ape.process_data((reference, estimate))
        ours = m[kind][cid]["ape"]
        assert ape.get_statistic(evo_metrics.StatisticsType.rmse) == pytest.approx(ours["rmse"], abs=1e-3), (cid, "rmse")
        assert ape.get_statistic(evo_metrics.StatisticsType.max) == pytest.approx(ours["max"], abs=1e-3), (cid, "max")
        assert float(np.percentile(ape.error, 95)) == pytest.approx(ours["p95"], abs=1e-3), (cid, "p95")
        assert estimate.num_poses == round(m[kind][cid].get("available", 1.0) * m["run"]["scans"])


def test_metrics_match_the_files(short_run):
    m = json.loads((short_run.out_dir / "metrics.json").read_text())
    assert m["run"]["scans"] == 300 and m["run"]["fixes"] == 150
    truth = files.read_tum(short_run.out_dir / "groundtruth.tum")
    ekf = files.read_tum(short_run.out_dir / "ekf.tum")
    common, i, j = np.intersect1d(truth[:, 0], ekf[:, 0], return_indices=True)
    error = np.hypot(*(truth[i, 1:3] - ekf[j, 1:3]).T)
    assert m["estimators"]["ekf"]["ape"]["max"] == pytest.approx(error.max(), abs=6e-5)  # metres to 0.1 mm (scenarios.score.units)
    assert m["estimators"]["ekf"]["available"] == pytest.approx(len(common) / len(truth), abs=5e-5)  # shares to 1e-4
    with open(short_run.out_dir / "gps.csv") as f:
        rows = list(csv.DictReader(f))
    measured = [float(r["err_h"]) for r in rows if r["quality"] in ("1", "2", "4", "5")]  # GGA: a measured position
    assert m["gps"]["availability"] == pytest.approx(len(measured) / len(rows))
    assert m["gps"]["error"]["max"] == pytest.approx(max(measured), abs=1e-3)
    assert m["run"]["realtime_factor"] > 0 and m["run"]["peak_rss_mb"] > 100
    assert [e["expect"] for e in m["expectations"]] == short_run.scenario.expect


def test_metrics_json_states_its_units_and_rounds_to_them(short_run):
    from scenarios.batch import table
    from scenarios.score import baseline, units

    m = json.loads((short_run.out_dir / "metrics.json").read_text())
    assert m["units"] == units.block() and list(m)[-1] == "units"
    flat = baseline.flatten(m)
    assert not any(path.startswith("units") for path in [*flat, *table.flatten(m)])
    for path, value in flat.items():
        quantity = units.quantity_of(path)
        assert quantity is not None, path
        if quantity.decimals is not None and value is not None:
            assert round(value, quantity.decimals) == value, path
    assert m["estimators"]["ekf"]["ape"]["p95"] == round(m["estimators"]["ekf"]["ape"]["p95"], 4)
    for outcome in m["expectations"]:  # each verdict judged the number metrics.json shows
        path = outcome["expect"].split()[0]
        assert outcome["value"] == flat[path], path


def test_nmea_log_has_valid_checksums(short_run):
    lines = (short_run.out_dir / "gps.nmea").read_bytes().split(b"\r\n")
    sentences = [line.decode() for line in lines if line]
    assert sum(s.startswith("$GNGGA") for s in sentences) == 150  # a multi-GNSS receiver: talker GN
    for s in sentences:
        body, checksum = s[1:].split("*")
        assert int(checksum, 16) == reduce(lambda a, c: a ^ ord(c), body, 0)


def test_same_scenario_same_outputs_with_one_or_two_processes_and_from_the_resolved_file(short_run, tmp_path):
    resolved = validate(tomllib.loads((short_run.out_dir / "scenario.toml").read_text()))
    assert resolved.hash == short_run.scenario.hash
    again = scenarios.run(resolved, tmp_path / "again", workers=1, report=False)
    for name in ["groundtruth.tum", "ekf.tum", "pf.tum", "gicp.tum", "gps.csv", "gps.nmea", "windows.csv"]:
        assert (again.out_dir / name).read_bytes() == (short_run.out_dir / name).read_bytes(), name


def test_fusing_further_behind_the_matchers_changes_no_output(short_run, tmp_path, monkeypatch):
    # an open-loop run keeps PIPELINED_SCANS scans with the matchers before fusing the oldest; one ahead (as a closed loop
    # does) feeds the estimators the same inputs in the same order
    assert PIPELINED_SCANS > LOOKAHEAD_SCANS
    monkeypatch.setattr("scenarios.pipeline.runner.PIPELINED_SCANS", LOOKAHEAD_SCANS)
    again = scenarios.run(short_run.scenario, tmp_path / "one_ahead", workers=2, report=False)
    for name in ["groundtruth.tum", "ekf.tum", "pf.tum", "gicp.tum", "gps.csv", "gps.nmea", "windows.csv"]:
        assert (again.out_dir / name).read_bytes() == (short_run.out_dir / name).read_bytes(), name


def test_a_matcher_that_raises_fails_from_that_scan_on_and_the_run_goes_on(tmp_path, monkeypatch):
    from scenarios.pipeline import matcher_pool

    real_create = matcher_pool.matchers_pkg.create

    class Exploding:
        def __init__(self, inner):
            self.inner, self.calls = inner, 0

        def register(self, scan):
            self.calls += 1
            if self.calls == 40:
                raise RuntimeError("boom")
            return self.inner.register(scan)

    monkeypatch.setattr(matcher_pool.matchers_pkg, "create", lambda kind, **p: Exploding(real_create(kind, **p)))
    result = scenarios.run(short(), tmp_path / "run", workers=1, report=False)
    failures = result.metrics["run"]["failures"]
    assert failures[0]["component"] == "matcher" and "boom" in failures[0]["reason"]
    gicp = result.metrics["matchers"]["gicp"]
    assert gicp["failed"] and gicp["failed_at"] == pytest.approx(60.0 + 39 * 0.1)
    with open(result.out_dir / "scans.csv") as f:
        ok = [int(r["gicp.ok"]) for r in csv.DictReader(f)]
    assert sum(ok[1:39]) > 30 and sum(ok[39:]) == 0
    estimators = result.metrics["estimators"]  # the estimators went on, without odometry from scan 40
    assert not any(e["failed"] for e in estimators.values()) and estimators["gps_only"]["available"] > 0.3


@pytest.mark.slow  # tests/test_plugins.py's failing plugins cover it (an estimator raising inside a run, the others going on)
def test_an_estimator_that_raises_is_recorded_and_the_others_go_on(tmp_path, monkeypatch):
    from fusion.pf import Pf

    def broken(self, stamp, match):
        raise FloatingPointError("pf exploded")

    monkeypatch.setattr(Pf, "add_match", broken)
    result = scenarios.run(short(), tmp_path / "run", workers=1, report=False)
    assert result.metrics["estimators"]["pf"]["failed"]
    assert result.metrics["estimators"]["ekf"]["available"] > 0.3 and not result.metrics["estimators"]["ekf"]["failed"]


@pytest.mark.parametrize("workers", [1, 2])
def test_a_simulation_failure_names_the_scan_and_leaves_nothing(tmp_path, monkeypatch, workers):
    # one process casts in sim.HDL32E.scan; two cast ahead in a worker, whose failure ScanAhead.scan raises
    # (tests/test_scan_ahead.py: the worker's own failure reaches it, word for word)
    owner, real_scan = (sim.HDL32E, sim.HDL32E.scan) if workers == 1 else (ScanAhead, ScanAhead.scan)

    def failing(self, *args):
        if args[-1] > 61.0:
            raise ValueError("lidar: trajectory gave a NaN pose")
        return real_scan(self, *args)

    monkeypatch.setattr(owner, "scan", failing)
    with pytest.raises(RunFailed, match=r"scan \d+ at t=61\.\d+ s: lidar: trajectory gave a NaN pose"):
        scenarios.run(short(), tmp_path / "run", workers=workers, report=False)
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_stops_cleanly_and_leaves_nothing(tmp_path):
    def interrupt(t, t0, t1, scans):
        if scans == 20:
            raise KeyboardInterrupt

    with pytest.raises(RunInterrupted, match="nothing written"):
        scenarios.run(short(), tmp_path / "run", workers=2, report=False, progress=interrupt)
    assert list(tmp_path.iterdir()) == []


KILLED_LANE = """
import os, signal, time
import numpy as np
from scenarios.pipeline.matcher_pool import MatcherPool, MatcherSetup
from sim.scan import POINT_DTYPE, Scan

if __name__ == "__main__":
    pool = MatcherPool([MatcherSetup("gicp", "gicp", {})], workers=2)  # gicp on the worker's lane
    points = np.zeros(60_000, dtype=POINT_DTYPE)
    points["x"], points["y"], points["z"] = np.random.default_rng(0).normal(scale=20.0, size=(3, 60_000))
    for k in range(10):  # more scans than the pipe to the worker holds: its feeder thread is left writing
        pool.submit(Scan(stamp=0.1 * k, points=points))
    os.kill(pool._procs[0][0].pid, signal.SIGTERM)  # what a `kill` of the whole process group does to the worker
    time.sleep(0.5)
    pool.close()
"""


def test_a_matcher_worker_killed_with_scans_unread_does_not_hold_the_process_exit(tmp_path):
    # the kill-group CI hang (tests/test_cli.py): the caller printed "stopped" and then waited forever at exit, joining its
    # queue's feeder thread, blocked writing scans into a pipe only the dead worker read
    script = tmp_path / "killed_lane.py"
    script.write_text(KILLED_LANE)
    env = {**os.environ, "PYTHONPATH": str(Path(scenarios.__file__).parents[1])}
    done = subprocess.run([sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr


def test_refuses_a_non_empty_output_directory(tmp_path):
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "keep.txt").write_text("mine")
    with pytest.raises(ValueError, match="not empty"):
        scenarios.run(short(), tmp_path / "run", report=False)
    assert (tmp_path / "run" / "keep.txt").read_text() == "mine"


def test_every_scan_has_each_estimators_protection_level_and_the_metrics_score_it(short_run):
    """scans.csv's <id>.hpl is the level each estimator reported at that scan; metrics.json's integrity figures are those
    of the levels against the errors of the TUM files (scenarios.score.metrics.integrity_metrics)."""
    from scenarios.score.metrics import integrity_metrics

    with open(short_run.out_dir / "scans.csv") as f:
        rows = list(csv.DictReader(f))
    truth = files.read_tum(short_run.out_dir / "groundtruth.tum", scenario_time=True)
    for e in short_run.scenario.estimators:
        level = np.array([float(r[f"{e.id}.hpl"]) if r[f"{e.id}.hpl"] else np.nan for r in rows])
        assert np.isfinite(level).mean() > 0.5 and (level[np.isfinite(level)] > 0).all()
        est = files.read_tum(short_run.out_dir / f"{e.id}.tum", scenario_time=True)
        at = np.searchsorted(truth[:, 0], est[:, 0] - 1e-6)
        error = np.full(len(rows), np.nan)
        error[at] = np.hypot(est[:, 1] - truth[at, 1], est[:, 2] - truth[at, 2])
        expected = integrity_metrics(error, level, short_run.scenario.integrity.alert_limit_m)
        node = short_run.metrics["estimators"][e.id]["integrity"]
        assert node["misleading_epochs"] == expected["misleading_epochs"] and node["hazardous_epochs"] == expected["hazardous_epochs"]
        assert node["available"] == pytest.approx(expected["available"], abs=1e-4)


def test_every_refused_fix_names_its_rule_and_the_rules_add_up_to_the_false_alarm_rate(tmp_path):
    """gps.csv's <id>.rule names the test that refused each fix (fusion.Verdict.rule) and is empty where the fix was
    trusted; the report's count by rule (scenarios.report.refusals) adds up to metrics.json's false-alarm rate. 25 s of
    busy_waterway around the Harvard Bridge's blackout: the ekf refuses fixes there (cn0 and the re-acquisition guard)."""
    from scenarios.report import plots
    from scenarios.report.refusals import by_rule, rules_of

    result = scenarios.run(scenarios.load("busy_waterway", set=["stretch={start_s = 845.0, end_s = 870.0}"]), tmp_path / "run", report=False)
    gps = plots.read_csv(result.out_dir / "gps.csv")
    for e in result.scenario.estimators:
        rules, trusted = rules_of(gps, e.id), gps[f"{e.id}.trusted"]
        assert ((rules == "") == (trusted == 1)).all(), e.id
        counts, good = by_rule(gps, e.id)
        node = result.metrics["estimators"][e.id]["monitor"]["added_5m"]
        if counts:
            assert sum(c.false_alarms for c in counts) / good == pytest.approx(node["false_alarm_rate"], abs=1e-4)
    ekf_rules = set(rules_of(gps, "ekf").tolist()) - {""}
    assert "consistency.guard" in {part for r in ekf_rules for part in r.split("+")}
    assert all(part.split(".")[0] in {"consistency", "cn0", "input"} for r in ekf_rules for part in r.split("+"))
