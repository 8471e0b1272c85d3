"""One point of a sweep as a backend runs it (local process or Ray task): the job, its outcome, and the run itself."""

from __future__ import annotations

import time
from dataclasses import dataclass

from scenarios.batch.plan import SweepPoint


@dataclass(frozen=True)
class Job:
    """What a backend runs: a point, where its run directory goes, with or without report, processes inside."""

    point: SweepPoint
    run_dir: str
    report: bool
    workers: int


@dataclass(frozen=True)
class JobOutcome:
    """A finished job: 'ok' with the run's metrics, or 'failed' with the reason."""

    status: str
    wall_s: float
    metrics: dict | None = None
    reason: str = ""


def run_job(job: Job) -> JobOutcome:
    """Load and run one point into job.run_dir; a run's own failure is an outcome, not an exception."""
    from scenarios.pipeline.runner import run

    start = time.perf_counter()
    try:
        scenario = job.point.scenario()
        result = run(scenario, job.run_dir, workers=job.workers, report=job.report)
    except Exception as exc:  # recorded with its reason; the sweep goes on
        return JobOutcome("failed", time.perf_counter() - start, reason=f"{type(exc).__name__}: {exc}".splitlines()[0])
    return JobOutcome("ok", time.perf_counter() - start, result.metrics)
