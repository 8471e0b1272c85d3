"""`riverbench sweep` (scenarios.batch.sweep.run_sweep): run a SweepPlan on a local process pool or on Ray.

A sweep directory holds sweep.json (the plan), results.csv and, with pyarrow, results.parquet (a row per run, see
scenarios.batch.table), runs/<scenario>-<hash>/ (each run's directory) and plots/. It is resumable:
a point whose resolved-scenario hash is in the table, or whose run directory was finished before the
table was written, is not run again; a failed run is a row with its reason and the sweep goes on.
"""

from __future__ import annotations

import json
import shutil
import statistics
import warnings
from collections.abc import Callable, Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from riverbench import provenance
from riverbench.atomic import atomic_path
from scenarios.batch import table
from scenarios.batch.job import Job, JobOutcome, run_job
from scenarios.batch.plan import SweepPlan, SweepPoint
from scenarios.batch.workers import JobResult, run_jobs

PLAN_FILE = "sweep.json"
RUNS = "runs"


@dataclass
class SweepResult:
    """The sweep's table (every row, in plan order), how many runs this call made, and where it is."""

    out_dir: Path
    rows: list[dict]
    ran: int
    skipped: int

    @property
    def failed(self) -> list[dict]:
        return [r for r in self.rows if r["status"] != "ok"]


def run_sweep(
    plan: SweepPlan,
    out_dir: Path,
    *,
    workers: int = 2,
    backend: str = "local",
    address: str | None = None,
    lean: bool = False,
    retry_failed: bool = False,
    on_start: Callable[[int, int], None] | None = None,
    on_row: Callable[[dict], None] | None = None,
    points: list[SweepPoint] | None = None,
) -> SweepResult:
    """Run every point of `plan` not already in out_dir's table; rewrite the table after each run.

    on_start(to_run, skipped) is called once the work is known, on_row(row) after each run.
    """
    if backend not in ("local", "ray"):
        raise ValueError(f"--backend {backend!r}: use local or ray")
    points = plan.points() if points is None else points
    out_dir = Path(out_dir)
    check_out_dir(out_dir)
    rows = {r["scenario_hash"]: r for r in table.read(out_dir)}
    todo = []
    for point in points:
        done = rows.get(point.hash)
        if done is not None and not (retry_failed and done["status"] != "ok"):
            continue
        recovered = recover(out_dir, point)
        if recovered is not None:
            rows[point.hash] = recovered
        else:
            todo.append(point)
    write_plan(out_dir, plan)
    remove_stale_temporaries(out_dir)
    order = [p.hash for p in points]
    planned = set(order)

    def save() -> list[dict]:
        """Rewrite the table: this plan's rows in plan order, then rows of earlier plans in the same directory."""
        ordered = [rows[h] for h in order if h in rows] + [r for h, r in rows.items() if h not in planned]
        table.write(out_dir, ordered)
        return ordered

    save()
    if on_start is not None:
        on_start(len(todo), len(points) - len(todo))
    jobs = [Job(p, str((out_dir / RUNS / p.run_name).resolve()), not lean, 2 if workers == 1 else 1) for p in todo]
    results = _backend(backend, jobs, workers, address)
    try:
        for result in results:
            point = jobs[result.index].point
            rows[point.hash] = _row(point, result)
            save()
            if on_row is not None:
                on_row(rows[point.hash])
    finally:
        results.close()
    return SweepResult(out_dir, save(), len(todo), len(points) - len(todo))


def _backend(backend: str, jobs: list[Job], workers: int, address: str | None) -> Iterator[JobResult]:
    if backend == "ray":
        from scenarios.batch.ray_backend import run_on_ray

        return run_on_ray(jobs, workers, address)
    return run_jobs(run_job, jobs, workers)


def _row(point: SweepPoint, result: JobResult) -> dict:
    """The table row of a backend's result (a job that could not even report is a failed run)."""
    if not result.ok:
        return table.row(point, "failed", float("nan"), "", reason=result.error)
    outcome: JobOutcome = result.value
    if outcome.status != "ok":
        return table.row(point, "failed", outcome.wall_s, "", reason=outcome.reason)
    return table.row(point, "ok", outcome.wall_s, f"{RUNS}/{point.run_name}", outcome.metrics)


def recover(out_dir: Path, point: SweepPoint) -> dict | None:
    """The row of a point whose run directory finished (renamed into place) before the table was written."""
    metrics_path = out_dir / RUNS / point.run_name / "metrics.json"
    if not metrics_path.exists():
        return None
    metrics = json.loads(metrics_path.read_text())
    if metrics.get("run", {}).get("scenario_hash") != point.hash:
        return None
    return table.row(point, "ok", metrics["run"].get("wall_s"), f"{RUNS}/{point.run_name}", metrics)


def remove_stale_temporaries(out_dir: Path) -> None:
    """Remove what a killed sweep's runs left half-written (hidden temporary directories in runs/)."""
    for stale in (out_dir / RUNS).glob(".*"):
        shutil.rmtree(stale, ignore_errors=True)


def check_out_dir(out_dir: Path) -> None:
    """A sweep goes into a new or empty directory, or resumes in one that holds a sweep."""
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"output directory {out_dir} is a file")
    if out_dir.exists() and any(out_dir.iterdir()) and not (out_dir / PLAN_FILE).exists():
        raise ValueError(f"output directory {out_dir} is not empty and holds no sweep ({PLAN_FILE}) to resume")


def write_plan(out_dir: Path, plan: SweepPlan) -> None:
    """sweep.json: the plan, so a reader knows what was swept (the table has every run's values)."""
    data = {**asdict(plan), "provenance": provenance.collect()}
    with atomic_path(out_dir / PLAN_FILE) as tmp:
        tmp.write_text(json.dumps(data, indent=2, default=list) + "\n")


def metric_names(point: SweepPoint) -> set[str]:
    """Every column a run of this point's scenario puts in the table (from an empty run's metrics and its command
    components' nodes)."""
    from scenarios.pipeline import external
    from scenarios.pipeline.runner import RUN_NUMBERS
    from scenarios.score import metrics, vessel_log
    from scenarios.score.record import Recorder

    scenario = point.scenario()
    record = Recorder([m.id for m in scenario.matchers], [e.id for e in scenario.estimators], np.eye(4)).finish([])
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        tree = metrics.compute(record, [], dict.fromkeys(RUN_NUMBERS, 0.0), vessel_log.metrics(vessel_log.VesselLog(), 0.0, 0.1))
        for section, spec in scenario.commands:
            tree[section][spec.id] = external.template(section)
    return set(table.flatten(metrics.json_safe(tree))) | set(table.IDENTITY) - {"scenario", "scenario_hash", "status", "reason", "run_dir"}


def check_metric(metric: str, points: list[SweepPoint], option: str = "--objective") -> None:
    """ValueError naming the option and metric when no scenario of the sweep has that metric."""
    names: set[str] = set()
    for source in dict.fromkeys(p.source for p in points):
        names |= metric_names(next(p for p in points if p.source == source))
    if metric not in names:
        near = sorted(n for n in names if n.split(".")[:2] == metric.split(".")[:2])[:6]
        hint = f"; e.g. {', '.join(near)}" if near else "; e.g. estimators.<id>.ape.p95, matchers.<id>.success"
        raise ValueError(f"{option} {metric!r}: no such metric in these runs{hint}")


@dataclass(frozen=True)
class Ranked:
    """One parameter combination of one scenario: the objective over its seeds."""

    scenario: str
    params: dict
    values: list[float]

    @property
    def median(self) -> float:
        return statistics.median(self.values)


def rank(rows: list[dict], objective: str, minimize: bool = True) -> list[Ranked]:
    """Parameter combinations (per scenario) ordered by the median objective over their seeds, best first."""
    groups: dict[tuple, Ranked] = {}
    for r in rows:
        value = r.get(objective)
        if r["status"] != "ok" or value is None or value != value:
            continue
        params = {k.removeprefix(table.PARAM_PREFIX): v for k, v in r.items() if k.startswith(table.PARAM_PREFIX)}
        key = (r["scenario"], json.dumps(params, sort_keys=True, default=str))
        groups.setdefault(key, Ranked(r["scenario"], params, [])).values.append(float(value))
    return sorted(groups.values(), key=lambda g: g.median if minimize else -g.median)


def write_plots(result: SweepResult, plan: SweepPlan, objective: str | None, extra: list[str]) -> list[Path]:
    """plots/: the objective, each --plot metric, or by default every estimator's APE p95 and matcher's success, against each swept key."""
    from scenarios.batch import sweep_plots

    groups = [[m] for m in dict.fromkeys([objective, *extra]) if m] or sweep_plots.default_metrics(result.rows)
    log_keys = {r.key for r in plan.ranges if r.log}
    return sweep_plots.write(result.out_dir, result.rows, [k for k in plan.keys if k != "seed"], groups, log_keys)
