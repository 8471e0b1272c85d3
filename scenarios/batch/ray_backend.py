"""The Ray backend of sweeps: each run is a Ray task on a local Ray instance or an existing cluster.

A task runs into a scratch directory on whichever node it lands, and ships the finished run
directory back as a tar archive, so the sweep directory needs no shared file system. Ray is an
optional extra (`pip install riverbench[ray]`); the nodes of a cluster need riverbench installed.
"""

from __future__ import annotations

import io
import logging
import os
import shutil
import tarfile
import tempfile
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

from riverbench.errors import one_line
from scenarios.batch.workers import JobResult


def import_ray():
    """The ray module, or a one-line ValueError saying how to install it."""
    try:
        import ray
    except ImportError:
        raise ValueError("--backend ray needs Ray, which is not installed: pip install 'riverbench[ray]'") from None
    return ray


def run_packed(job) -> tuple:
    """Ray task: run the job in a scratch directory; return its outcome and the run directory as a tar archive."""
    from scenarios.batch.job import run_job

    scratch = Path(tempfile.mkdtemp(prefix="riverbench-ray-"))
    try:
        outcome = run_job(replace(job, run_dir=str(scratch / "run")))
        archive = io.BytesIO()
        if outcome.status == "ok":
            with tarfile.open(fileobj=archive, mode="w:gz") as tar:
                tar.add(scratch / "run", arcname=".")
        return outcome, archive.getvalue()
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def unpack(archive: bytes, run_dir: Path) -> None:
    """Extract a shipped run directory into place: under a temporary name, then renamed."""
    run_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{run_dir.name}.", dir=run_dir.parent))
    try:
        with tarfile.open(fileobj=io.BytesIO(archive), mode="r:gz") as tar:
            tar.extractall(tmp, filter="data")
        os.chmod(tmp, 0o755)
        if run_dir.exists():
            shutil.rmtree(run_dir)
        os.replace(tmp, run_dir)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def run_on_ray(jobs: list, workers: int, address: str | None) -> Iterator[JobResult]:
    """Submit every job as a task; yield each result as it finishes (its run directory already in place).

    Without an address a local Ray instance with `workers` CPUs is started (and shut down at the end);
    with one, the cluster schedules the tasks on all its CPUs.
    """
    ray = import_ray()
    started = not ray.is_initialized()
    if started:
        ray.init(
            address=address,
            num_cpus=None if address else workers,
            include_dashboard=False,
            log_to_driver=False,
            logging_level=logging.ERROR,
            configure_logging=True,
        )
    task = ray.remote(num_cpus=1, max_retries=0)(run_packed)
    pending = {task.remote(job): i for i, job in enumerate(jobs)}
    try:
        while pending:
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                index = pending.pop(ref)
                try:
                    outcome, archive = ray.get(ref)
                except Exception as exc:  # the task or its node died: that run's failure
                    yield JobResult(index, False, error=f"ray task failed: {one_line(exc)}")
                    continue
                if outcome.status == "ok":
                    unpack(archive, Path(jobs[index].run_dir))
                yield JobResult(index, True, outcome)
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()
