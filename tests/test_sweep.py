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
from scenarios.batch.plan import SAMPLERS, Axis, Range, SweepPlan, unit_samples
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


def sampled(sampler: str, n: int, *ranges: str, seed: int = 0) -> list[dict]:
    plan = SweepPlan(("canal_multipath",), ranges=tuple(Range.parse(r) for r in ranges), samples=n, sampler=sampler, sample_seed=seed)
    return plan.combinations()


@given(
    lo=st.floats(1e-4, 10.0),
    span=st.floats(1.01, 1e3),
    log=st.booleans(),
    sampler=st.sampled_from(SAMPLERS),
    seed=st.integers(0, 2**32 - 1),
)
def test_samples_stay_in_their_range_and_repeat_with_the_sample_seed(lo, span, log, sampler, seed):
    key = f"k={lo!r}:{lo * span!r}" + (":log" if log else "")
    a, b = sampled(sampler, 16, key, "j=0:3", seed=seed), sampled(sampler, 16, key, "j=0:3", seed=seed)
    assert a == b and len(a) == 16
    assert all(lo <= c["k"] <= lo * span and type(c["k"]) is float for c in a)
    assert all(c["j"] in (0, 1, 2, 3) and type(c["j"]) is int for c in a)
    assert a != sampled(sampler, 16, key, "j=0:3", seed=seed + 1)


@pytest.mark.parametrize("n", [1, 7, 64, 300])
def test_a_latin_hypercube_puts_one_sample_in_each_of_n_strata_of_every_key(n):
    combos = sampled("lhs", n, "lidar.range_noise_m=0.01:0.05", "gnss.rate_hz=1.0:1000.0:log", "other=-3.0:5.0")
    noise = np.array([c["lidar.range_noise_m"] for c in combos])
    rate = np.log10([c["gnss.rate_hz"] for c in combos])  # log-scaled: the strata are equal in log space
    other = np.array([c["other"] for c in combos])
    for unit in ((noise - 0.01) / 0.04, (rate - 0.0) / 3.0, (other + 3.0) / 8.0):
        assert sorted(np.minimum(np.floor(unit * n), n - 1).astype(int)) == list(range(n))


def test_log_scaled_keys_spread_evenly_over_the_decades_and_integer_keys_over_their_values():
    combos = sampled("lhs", 300, "lidar.range_noise_m=0.001:1.0:log", "vessel.sea_state=0:3")
    logs = np.log10([c["lidar.range_noise_m"] for c in combos])
    assert list(np.histogram(logs, bins=3, range=(-3, 0))[0]) == [100, 100, 100]  # a stratum per sample: exactly a third a decade
    assert [sum(c["vessel.sea_state"] == k for c in combos) for k in range(4)] == [75, 75, 75, 75]
    uniform = np.log10([c["lidar.range_noise_m"] for c in sampled("random", 4000, "lidar.range_noise_m=0.001:1.0:log")])
    assert np.histogram(uniform, bins=3, range=(-3, 0))[0].min() > 1200  # plain random: a third in each decade, on average


def test_sobol_points_need_a_power_of_two_and_the_sampler_must_be_known():
    assert len(sampled("sobol", 16, "lidar.range_noise_m=0.01:0.05")) == 16
    with pytest.raises(ValueError, match=r"--sampler sobol: N must be a power of 2 .*got 10; use 8 or 16"):
        sampled("sobol", 10, "lidar.range_noise_m=0.01:0.05")
    with pytest.raises(ValueError, match="--sampler 'halton': use one of lhs, sobol, random"):
        sampled("halton", 10, "lidar.range_noise_m=0.01:0.05")


def test_quasi_random_samplers_cover_the_box_more_evenly_than_random_draws():
    """The point of --sampler: lower centred L2 discrepancy (scipy.stats.qmc.discrepancy) than plain random draws, in
    the median over seeds (benchmarks/sampling.py prints the figures)."""
    from scipy.stats import qmc

    median = {s: np.median([qmc.discrepancy(unit_samples(s, 64, 3, seed)) for seed in range(20)]) for s in SAMPLERS}
    assert median["sobol"] < median["random"] and median["lhs"] < median["random"]


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


def test_fast_sweeps_each_scenarios_fast_variant_and_refuses_a_scenario_without_one():
    points = SweepPlan(("quickstart",), seeds=2, fast=True).points()
    fast = load("quickstart").fast_variant()
    assert [p.scenario().stretch for p in points] == [fast.stretch] * 2 and points[0].scenario().expect == fast.expect
    assert points[0].hash == load("quickstart", seed=0).fast_variant().hash != SweepPlan(("quickstart",), seeds=2).points()[0].hash
    with pytest.raises(ValueError, match=r"^open_river: no \[fast\] variant"):
        SweepPlan(("open_river",), seeds=2, fast=True).points()
    with pytest.raises(ValueError, match=r"^stretch: overridden, but --fast runs the \[fast\] table's stretch"):
        SweepPlan(("quickstart",), grid=(Axis.parse("stretch={start_s = 0.0, end_s = 5.0},{start_s = 0.0, end_s = 6.0}"),), fast=True).points()


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
        "--set",
        "expect=[]",  # the short stretch misses the scenario's expectations; this test is about resuming (exit 0)
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


@pytest.mark.parametrize(
    ("signum", "code"),
    [(signal.SIGINT, 130), pytest.param(signal.SIGTERM, 143, marks=pytest.mark.slow)],  # ~16 s each; tests/test_cli.py kills a run fast
    ids=["ctrl-c", "kill"],
)
def test_a_stopped_sweep_keeps_the_finished_runs_in_the_table_and_leaves_nothing_hidden(tmp_path, signum, code):
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
    os.killpg(proc.pid, signum)  # the whole process group, as a terminal's Ctrl-C or a job runner's cancel does
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code and "the same command completes it" in err, err
    rows = pq.read_table(table).to_pylist()
    assert 1 <= len(rows) < 3
    assert not [p for p in (tmp_path / "sw").rglob(".*")]  # interrupted runs and table writes cleaned up


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
        (["--seeds", "2", "--fast"], "canal_multipath: no [fast] variant"),
        (["--sample", "10", "lidar.range_noise_m=0.01:0.05", "--sampler", "sobol"], "N must be a power of 2"),
        (["--sample", "10", "lidar.range_noise_m=0.01:0.05", "--sampler", "grid"], "--sampler 'grid'"),
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


def test_a_sweep_whose_runs_fail_an_expectation_says_how_many_and_exits_1(tmp_path, monkeypatch):
    from typer.testing import CliRunner

    from scenarios.cli import app

    monkeypatch.chdir(tmp_path)
    expect = 'expect=["gps.availability < 0.0"],["gps.availability >= 0.0"]'  # one run misses, one passes
    args = [
        "sweep",
        "canal_multipath",
        "--set",
        "stretch={start_s = 60.0, end_s = 61.0}",
        "--grid",
        expect,
        "--lean",
        "--workers",
        "1",
        "--out",
        "sw",
    ]
    result = CliRunner().invoke(app, args)
    said = " ".join(result.output.split())  # rich wraps at 80 columns
    assert result.exit_code == 1, result.output
    assert "1 of 2 runs failed an expectation: canal_multipath seed 0 expect=['gps.availability < 0.0']" in said
    assert "FAIL canal_multipath seed 0 expect=['gps.availability < 0.0']" in said and "1 of 1 expectations failed" in said
    assert "pass canal_multipath seed 0 expect=['gps.availability >= 0.0']" in said and "failed to run" not in said


def test_a_sweep_tells_runs_that_failed_to_run_from_runs_that_failed_an_expectation():
    from scenarios.batch.outcome import of_rows

    rows = [
        {"scenario": "s", "seed": 0, "status": "ok", "passed": True, "param.a": 1},
        {"scenario": "s", "seed": 0, "status": "ok", "passed": False, "param.a": 2},
        {"scenario": "s", "seed": 0, "status": "ok", "passed": False, "param.a": 0.123456},
        {"scenario": "s", "seed": 1, "status": "failed", "passed": None, "param.a": 2},
    ]
    verdict = of_rows(rows)
    assert verdict.exit_code == 1
    assert verdict.lines() == ["2 of 4 runs failed an expectation: s seed 0 a=2, s seed 0 a=0.1235", "1 of 4 runs failed to run: s seed 1 a=2"]
    assert of_rows(rows[:1]).lines() == ["1 of 1 runs passed every expectation"] and of_rows(rows[:1]).exit_code == 0


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
