"""Sweeps (scenarios.batch.sweep*, `riverbench sweep`): the plan's expansion and its errors, the results table,
the local and Ray backends giving the same table, resuming after a kill, failed runs, the worker pool."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from hypothesis import given
from hypothesis import strategies as st

from scenarios.batch import sweep as sweeping
from scenarios.batch import table as sweep_table
from scenarios.batch.plan import Axis, Range, SweepPlan
from scenarios.batch.workers import run_jobs
from scenarios.spec.library import load

SHORT = "stretch={start_s = 60.0, end_s = 70.0}"
"""10 s of the canal_multipath canyon: a run takes a few seconds."""
RIVERBENCH = [sys.executable, "-m", "scenarios.cli"]
TIMING = ("wall_s", "run.wall_s", "run.realtime_factor", "run.peak_rss_mb", "run.workers")


def timing(column: str) -> bool:
    """Columns that measure the machine, not the algorithms."""
    return column in TIMING or column.endswith(".hz") or ".ms." in column


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([*RIVERBENCH, *args], cwd=cwd, capture_output=True, text=True, timeout=600)


def small_plan(**more) -> SweepPlan:
    return SweepPlan(("canal_multipath",), grid=(Axis.parse("lidar.range_noise_m=0.01,0.05"),), seeds=2, fixed=(SHORT,), **more)


# ---- the plan ----------------------------------------------------------------------------------------


def test_grid_values_are_toml_and_commas_inside_brackets_do_not_split():
    axis = Axis.parse('stretch={start_s = 0.0, end_s = 10.0},{start_m = 5.0},"a,b",nis,3,0.5,[1, 2]')
    assert axis.values == ({"start_s": 0.0, "end_s": 10.0}, {"start_m": 5.0}, "a,b", "nis", 3, 0.5, [1, 2])


def test_grid_expands_to_the_cartesian_product_times_seeds_with_distinct_hashes():
    plan = SweepPlan(
        ("canal_multipath",),
        grid=(Axis.parse("lidar.range_noise_m=0.01,0.02,0.03"), Axis.parse("estimators.ekf.monitor=nis,none")),
        seeds=2,
        fixed=(SHORT,),
    )
    points = plan.points()
    assert len(points) == 12 and len({p.hash for p in points}) == 12
    assert {p.seed for p in points} == {0, 1}
    first = load("canal_multipath", set=list(points[0].assignments), seed=points[0].seed)
    assert first.lidar.range_noise_m == 0.01 and first.matcher_spec("gicp") is not None
    assert next(e for e in first.estimators if e.id == "ekf").monitor == "nis"
    assert points[0].run_name == f"canal_multipath-{first.hash}"


def test_the_same_point_twice_runs_once():
    assert len(SweepPlan(("canal_multipath",), grid=(Axis.parse("lidar.range_noise_m=0.02,0.020"),), fixed=(SHORT,)).points()) == 1


@given(lo=st.floats(1e-4, 10.0), span=st.floats(1.01, 1e3), log=st.booleans(), seed=st.integers(0, 2**32 - 1))
def test_samples_stay_in_their_range_and_repeat_with_the_sample_seed(lo, span, log, seed):
    r = Range("k", lo, lo * span, log)
    a, b = r.draw(np.random.default_rng(seed), 50), r.draw(np.random.default_rng(seed), 50)
    assert a == b and all(lo <= v <= lo * span for v in a) and all(type(v) is float for v in a)


def test_integer_bounds_sample_integers_and_log_ranges_are_log_uniform():
    ints = Range.parse("vessel.sea_state=0:3").draw(np.random.default_rng(0), 400)
    assert set(ints) == {0, 1, 2, 3}
    logs = np.log10(Range.parse("lidar.range_noise_m=0.001:1.0:log").draw(np.random.default_rng(0), 4000))
    assert np.histogram(logs, bins=3, range=(-3, 0))[0].min() > 1200  # a third of the draws in each decade


def test_samples_are_joint_and_crossed_with_the_grid():
    plan = SweepPlan(
        ("canal_multipath",),
        grid=(Axis.parse("estimators.ekf.monitor=nis,none"),),
        ranges=(Range.parse("lidar.range_noise_m=0.01:0.05"), Range.parse("vessel.sea_state=0:2")),
        samples=3,
        fixed=(SHORT,),
    )
    combos = plan.combinations()
    assert len(combos) == 6
    assert [c["lidar.range_noise_m"] for c in combos[:3]] == [c["lidar.range_noise_m"] for c in combos[3:]]
    assert combos == SweepPlan(plan.sources, plan.grid, plan.ranges, samples=3, fixed=plan.fixed).combinations()  # seeded draws


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Axis.parse("lidar.range_noise_m="), "no values"),
        (lambda: Axis.parse("=1,2"), "key=v1,v2"),
        (lambda: Range.parse("lidar.range_noise_m=0.05:0.01"), "lo must be below hi"),
        (lambda: Range.parse("lidar.range_noise_m=0:1:log"), "lo > 0"),
        (lambda: Range.parse("lidar.range_noise_m=a:b"), "finite numbers"),
        (lambda: SweepPlan(("canal_multipath",)), "nothing to sweep"),
        (lambda: SweepPlan(("canal_multipath",), grid=(Axis.parse("a=1,2"), Axis.parse("a=3"))), "swept twice"),
        (
            lambda: SweepPlan(("canal_multipath",), grid=(Axis.parse("lidar.no_such_key=1,2"),)).points(),
            "canal_multipath.toml: unknown key 'lidar.no_such_key'",
        ),
        (lambda: SweepPlan(("canal_multipath",), grid=(Axis.parse("lidar.range_noise_m=fast,slow"),)).points(), "lidar.range_noise_m"),
        (lambda: SweepPlan(("no_such_scenario",), seeds=2).points(), "unknown scenario 'no_such_scenario'"),
    ],
)
def test_bad_plans_fail_with_one_line_naming_the_problem(make, message):
    with pytest.raises(ValueError, match=message.replace("(", r"\(").replace(")", r"\)")) as err:
        make()
    assert "\n" not in str(err.value)


def test_the_objective_must_be_a_metric_the_runs_have():
    points = small_plan().points()
    sweeping.check_metric("estimators.ekf.ape.p95", points)
    sweeping.check_metric("matchers.gicp.success", points)
    with pytest.raises(ValueError, match=r"--objective 'estimators.ekf.ape.p96': no such metric.*estimators.ekf.ape.p95"):
        sweeping.check_metric("estimators.ekf.ape.p96", points)
    with pytest.raises(ValueError, match="no such metric"):
        sweeping.check_metric("estimators.kalman.ape.p95", points)


# ---- running: local and Ray give the same table ---------------------------------------------------------


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("sweep") / "local"
    return sweeping.run_sweep(small_plan(), out, workers=2, lean=True)


def test_a_local_sweep_writes_a_row_per_run_with_parameters_and_every_metric(local_sweep):
    rows = local_sweep.rows
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows)
    assert [(r["param.lidar.range_noise_m"], r["seed"]) for r in rows] == [(0.01, 0), (0.01, 1), (0.05, 0), (0.05, 1)]
    table = pq.read_table(local_sweep.out_dir / "results.parquet")
    assert table.to_pylist() == rows
    assert str(table.schema.field("estimators.ekf.ape.p95").type) == "double"
    assert str(table.schema.field("seed").type) == "int64" and str(table.schema.field("passed").type) == "bool"
    expected = sweeping.metric_names(small_plan().points()[0])
    assert set(table.column_names) - {"scenario", "scenario_hash", "status", "reason", "run_dir", "param.lidar.range_noise_m"} == expected
    for r in rows:
        run_dir = local_sweep.out_dir / r["run_dir"]
        assert (run_dir / "metrics.json").exists() and not (run_dir / "report.html").exists()  # --lean
        assert load(run_dir / "scenario.toml").hash == r["scenario_hash"]
    # the noise level reaches the LiDAR: the matcher's odometry differs between the two values
    by = {(r["param.lidar.range_noise_m"], r["seed"]): r["matchers.gicp.ape_aligned.rmse"] for r in rows}
    assert by[(0.01, 0)] != by[(0.05, 0)]


def test_the_csv_holds_the_same_values_as_the_parquet_table(local_sweep):
    import csv

    with open(local_sweep.out_dir / "results.csv", newline="") as f:
        csv_rows = list(csv.DictReader(f))
    assert len(csv_rows) == len(local_sweep.rows) > 0
    for r, c in zip(local_sweep.rows, csv_rows, strict=True):
        assert set(c) == set(r)
        for key, value in r.items():
            if isinstance(value, float):
                assert float(c[key]) == value or (math.isnan(value) and c[key] == "nan")
            elif value is None:
                assert c[key] == ""
            else:
                assert c[key] == str(value)


@pytest.mark.slow  # 12 s alone but minutes beside the fast suite (Ray's worker start-up starves); the local path covers the table code
def test_the_ray_backend_gives_the_same_table_to_the_last_bit(local_sweep, tmp_path):
    pytest.importorskip("ray")
    ray_result = sweeping.run_sweep(small_plan(), tmp_path / "ray", workers=2, backend="ray", lean=True)
    assert len(ray_result.rows) == len(local_sweep.rows)
    for a, b in zip(local_sweep.rows, ray_result.rows):
        assert a.keys() == b.keys()
        assert {k: v for k, v in a.items() if not timing(k)} == {k: v for k, v in b.items() if not timing(k)}
        assert (tmp_path / "ray" / b["run_dir"] / "groundtruth.tum").read_bytes() == (
            local_sweep.out_dir / a["run_dir"] / "groundtruth.tum"
        ).read_bytes()


def test_a_finished_sweep_run_again_runs_nothing(local_sweep):
    again = sweeping.run_sweep(small_plan(), local_sweep.out_dir, workers=2, lean=True)
    assert again.ran == 0 and again.skipped == 4 and again.rows == local_sweep.rows


def test_a_run_finished_before_the_table_was_written_is_recovered_not_redone(local_sweep, tmp_path):
    out = tmp_path / "recover"
    (out / "runs").mkdir(parents=True)
    first = local_sweep.rows[0]
    os.symlink(local_sweep.out_dir / first["run_dir"], out / first["run_dir"])
    (out / "runs" / ".canal_multipath-x.tmp").mkdir()  # what a killed run leaves
    (out / "sweep.json").write_text("{}")
    plan = SweepPlan(("canal_multipath",), grid=(Axis.parse("lidar.range_noise_m=0.01"),), fixed=(SHORT,))
    result = sweeping.run_sweep(plan, out, workers=1, lean=True)
    assert result.ran == 0 and result.rows[0]["run.scans"] == first["run.scans"]
    assert not (out / "runs" / ".canal_multipath-x.tmp").exists()


def test_a_failed_run_is_a_row_with_its_reason_and_the_sweep_goes_on(tmp_path):
    plan = SweepPlan(("canal_multipath",), grid=(Axis.parse("stretch={start_s = 60.0, end_s = 70.0},{start_s = 60.0, end_s = 99999.0}"),))
    result = sweeping.run_sweep(plan, tmp_path / "s", workers=2, lean=True)
    assert [r["status"] for r in result.rows] == ["ok", "failed"]
    assert "not inside the trajectory" in result.rows[1]["reason"] and result.rows[1]["run_dir"] == ""
    assert not [p for p in (tmp_path / "s" / "runs").iterdir() if p.name.startswith(".")]
    again = sweeping.run_sweep(plan, tmp_path / "s", workers=2, lean=True)
    assert again.ran == 0
    retried = sweeping.run_sweep(plan, tmp_path / "s", workers=2, lean=True, retry_failed=True)
    assert retried.ran == 1 and retried.rows[1]["status"] == "failed"
    from scenarios.report import compare  # the comparison report lists the failed run, which left no run directory

    compare.write([tmp_path / "s"], tmp_path / "report")
    text = (tmp_path / "report" / "report.md").read_text()
    assert "## Runs that did not finish" in text and "| **canal_multipath (seed 0)** | ValueError: stretch:" in text


def test_ranking_takes_the_median_over_seeds():
    rows = [{"scenario": "s", "status": "ok", "param.a": a, "m": m} for a, m in ((1, 5.0), (1, 1.0), (1, 2.0), (2, 3.0), (2, 3.5))]
    rows.append({"scenario": "s", "status": "failed", "param.a": 3})
    ranked = sweeping.rank(rows, "m")
    assert [(g.params, g.median) for g in ranked] == [({"a": 1}, 2.0), ({"a": 2}, 3.25)]
    assert [g.params["a"] for g in sweeping.rank(rows, "m", minimize=False)] == [2, 1]


# ---- the command line: kill and resume, bad input ---------------------------------------------------------


@pytest.mark.slow  # covered in the default run by the recover / skip / Ctrl-C tests; CI runs it with the slow ones
def test_a_killed_sweep_leaves_a_consistent_table_and_the_same_command_completes_it(tmp_path):
    args = [
        "sweep",
        "canal_multipath",
        "--grid",
        "lidar.range_noise_m=0.01,0.02,0.03,0.04",
        "--set",
        SHORT,
        "--workers",
        "1",
        "--lean",
        "--quiet",
        "--out",
        "sw",
    ]
    proc = subprocess.Popen([*RIVERBENCH, *args], cwd=tmp_path, start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    table = tmp_path / "sw" / "results.parquet"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and (not table.exists() or pq.read_table(table).num_rows < 1):
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGKILL)  # the sweep and every worker, mid-run
    proc.wait()
    before = pq.read_table(table).to_pylist()
    assert 1 <= len(before) < 4 and all(r["status"] == "ok" for r in before)
    done = cli(*args[:-2], "--out", "sw", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    after = pq.read_table(table).to_pylist()
    assert len(after) == 4 and all(r["status"] == "ok" for r in after)
    assert after[: len(before)] == before  # finished runs were not redone (same wall times)
    assert sorted(p.name for p in (tmp_path / "sw" / "runs").iterdir()) == sorted(r["run_dir"].split("/")[1] for r in after)


def test_ctrl_c_stops_the_sweep_with_the_finished_runs_in_the_table(tmp_path):
    args = [
        "sweep",
        "canal_multipath",
        "--grid",
        "lidar.range_noise_m=0.01,0.02,0.03",
        "--set",
        SHORT,
        "--workers",
        "1",
        "--lean",
        "--quiet",
        "--out",
        "sw",
    ]
    # a shell without job control starts background jobs with SIGINT ignored, and Python keeps an ignored SIGINT:
    # give the sweep the default disposition a terminal's foreground process has, whatever runs the tests
    proc = subprocess.Popen(
        [*RIVERBENCH, *args],
        cwd=tmp_path,
        start_new_session=True,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    table = tmp_path / "sw" / "results.parquet"
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and (not table.exists() or pq.read_table(table).num_rows < 1):
        time.sleep(0.2)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and "the same command completes it" in err
    rows = pq.read_table(table).to_pylist()
    assert 1 <= len(rows) < 3
    assert not [p for p in (tmp_path / "sw" / "runs").iterdir() if p.name.startswith(".")]  # interrupted runs cleaned up


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--grid", "lidar.no_such_key=1,2"], "canal_multipath.toml: unknown key 'lidar.no_such_key'"),
        (["--grid", "lidar.range_noise_m=fast,slow"], "lidar.range_noise_m"),
        (["--grid", "lidar.range_noise_m="], "no values"),
        (["--seeds", "2", "--objective", "estimators.ekf.ape.p96"], "no such metric"),
        (["--seeds", "2", "--plot", "matchers.gicp.speed"], "--plot 'matchers.gicp.speed'"),
        (["--sample", "3", "lidar.range_noise_m=0.05:0.01"], "lo must be below hi"),
        (["--seeds", "2", "--backend", "spark"], "--backend 'spark'"),
        ([], "nothing to sweep"),
    ],
)
def test_bad_sweep_input_is_one_line_exit_2_and_writes_nothing(tmp_path, monkeypatch, args, message):
    from typer.testing import CliRunner

    from scenarios.cli import app

    monkeypatch.chdir(tmp_path)
    result = CliRunner().invoke(app, ["sweep", "canal_multipath", *args, "--out", "sw"])
    assert result.exit_code == 2, result.output
    assert message in result.output and len(result.output.strip().splitlines()) == 1
    assert not (tmp_path / "sw").exists() and not (tmp_path / "runs").exists()


def test_a_missing_ray_is_one_line_saying_how_to_install_it(tmp_path):
    env = {**os.environ, "PYTHONPATH": str(tmp_path)}
    (tmp_path / "ray.py").write_text("raise ImportError('no ray here')\n")
    result = subprocess.run(
        [*RIVERBENCH, "sweep", "canal_multipath", "--seeds", "2", "--backend", "ray", "--out", "sw"],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 2 and "pip install 'riverbench[ray]'" in result.stderr
    assert not (tmp_path / "sw").exists()


# ---- the worker pool ----------------------------------------------------------------------------------------


def die_on_two(x: int) -> int:
    """A job that kills its worker process on 2 and raises on 3."""
    if x == 2:
        os._exit(7)
    if x == 3:
        raise RuntimeError("three")
    return x * x


def test_the_pool_survives_a_job_that_kills_its_worker_and_one_that_raises():
    results = {r.index: r for r in run_jobs(die_on_two, [1, 2, 3, 4, 5], workers=2)}
    assert {i: r.value for i, r in results.items() if r.ok} == {0: 1, 3: 16, 4: 25}
    assert "worker process died (exit code 7)" in results[1].error
    assert results[2].error == "RuntimeError: three"


def test_sweep_plots_draw_the_median_over_seeds(local_sweep):
    from scenarios.batch import sweep_plots

    lines = sweep_plots.lines(local_sweep.rows, ["matchers.gicp.ape_aligned.rmse"], "lidar.range_noise_m")
    assert len(lines) == 1 and lines[0].x == [0.01, 0.05]
    assert [sorted(v) for v in lines[0].values] == [
        sorted(r["matchers.gicp.ape_aligned.rmse"] for r in local_sweep.rows if r["param.lidar.range_noise_m"] == x) for x in (0.01, 0.05)
    ]
    written = sweeping.write_plots(local_sweep, small_plan(), None, [])
    assert {p.name for p in written} == {"estimators.all.ape.p95--lidar.range_noise_m.png", "matchers.gicp.success--lidar.range_noise_m.png"}
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in written)


def test_table_flattening_counts_lists_and_keeps_nulls():
    flat = sweep_table.flatten(
        {
            "run": {"wall_s": 1.5, "scenario": "x", "failures": [{"id": "a"}], "lanes": [["gicp"]]},
            "estimators": {"ekf": {"ape": {"p95": None}, "failed": False}},
            "expectations": [{"pass": True}, {"pass": False}, {"pass": True}],
        }
    )
    assert flat == {
        "run.wall_s": 1.5,
        "run.failures": 1,
        "estimators.ekf.ape.p95": None,
        "estimators.ekf.failed": False,
        "expectations.passed": 2,
        "expectations.failed": 1,
    }


def test_without_pyarrow_the_csv_is_the_table_and_reads_back_the_same_rows(local_sweep, tmp_path, monkeypatch):
    from scenarios.batch import table

    monkeypatch.setattr(table, "_pyarrow", lambda: None)
    table.write(tmp_path, local_sweep.rows)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["results.csv"]
    back = table.read(tmp_path)
    assert len(back) == len(local_sweep.rows)
    for r, b in zip(local_sweep.rows, back, strict=True):
        assert b.keys() == r.keys()
        for key, value in r.items():
            if isinstance(value, float) and math.isnan(value):
                assert math.isnan(b[key])
            else:
                assert b[key] == value, key
