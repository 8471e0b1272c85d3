"""A pool of long-lived worker processes for sweeps: imports are paid once per worker, not per run.

Each worker runs one job at a time. A job that raises comes back as a failure with its reason; a
worker that dies (a crash, the OOM killer) fails the job it held and is replaced; on Ctrl-C or any
error in the caller the workers get SIGTERM, which unwinds a run so it removes its temporary files.
"""

from __future__ import annotations

import multiprocessing as mp
import signal
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from multiprocessing.connection import Connection, wait


class Terminated(BaseException):
    """SIGTERM from the parent (time-out, Ctrl-C): unwind so a run removes its temporary directory."""


def raise_terminated(signum, frame) -> None:
    """Raise Terminated once; later SIGTERMs (the parent's stop() after a `kill` of the whole process group) are ignored
    so that they cannot cut the run's clean-up short (stop() ends a process that takes too long with SIGKILL)."""
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    raise Terminated


def stop(proc: mp.Process, grace_s: float = 30.0) -> None:
    """SIGTERM (a run unwinds and cleans up), then SIGKILL if it has not ended within grace_s."""
    proc.terminate()
    proc.join(grace_s)
    if proc.is_alive():
        proc.kill()
        proc.join()


@dataclass
class JobResult:
    """What came back for job `index`: its value, or why it failed."""

    index: int
    ok: bool
    value: object = None
    error: str = ""


def _serve(conn: Connection) -> None:
    """Worker loop: receive (function, argument), send back (True, value) or (False, reason); None ends it."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle; it terminates us
    signal.signal(signal.SIGTERM, raise_terminated)
    try:
        while (job := conn.recv()) is not None:
            fn, arg = job
            try:
                conn.send((True, fn(arg)))
            except Exception as exc:  # the job's failure, reported; the worker serves on
                conn.send((False, f"{type(exc).__name__}: {exc}"))
    except (Terminated, EOFError):  # stopped by the parent (the job unwound and cleaned up), or the parent is gone
        return


@dataclass
class _Worker:
    proc: mp.Process
    conn: Connection
    job: int | None = None

    @staticmethod
    def spawn(ctx) -> _Worker:
        parent, child = ctx.Pipe()
        proc = ctx.Process(target=_serve, args=(child,), daemon=False)  # not a daemon: a run may start its own workers
        proc.start()
        child.close()
        return _Worker(proc, parent)


def _give(ctx, worker: _Worker, index: int, job: tuple) -> _Worker:
    """Send a job to the worker, or to a fresh one if it has died; returns the worker that holds it."""
    if worker.proc.is_alive():
        try:
            worker.conn.send(job)
            worker.job = index
            return worker
        except (BrokenPipeError, OSError):
            stop(worker.proc)
    fresh = _Worker.spawn(ctx)
    fresh.conn.send(job)
    fresh.job = index
    return fresh


def run_jobs(fn: Callable, args: list, workers: int) -> Iterator[JobResult]:
    """Run fn(arg) for every arg on `workers` processes; yield each result as it finishes.

    fn must be importable (spawned workers unpickle it by name). Closing the iterator early (or an
    exception in the caller) stops the workers.
    """
    ctx = mp.get_context("spawn")
    pending = deque(enumerate(args))
    pool = [_Worker.spawn(ctx) for _ in range(min(workers, len(args)))]
    try:
        while pending or any(w.job is not None for w in pool):
            for i, w in enumerate(pool):
                if w.job is None and pending:
                    index, arg = pending.popleft()
                    pool[i] = _give(ctx, w, index, (fn, arg))
            busy = [w for w in pool if w.job is not None]
            wait([w.conn for w in busy] + [w.proc.sentinel for w in busy], timeout=1.0)
            for w in pool:
                if w.job is None:
                    continue
                if w.conn.poll():
                    try:
                        ok, value = w.conn.recv()
                    except (EOFError, OSError):  # it died: its end of the pipe closed
                        w.proc.join()
                        ok, value = False, f"worker process died (exit code {w.proc.exitcode})"
                    index, w.job = w.job, None
                    yield JobResult(index, True, value) if ok else JobResult(index, False, error=value)
                elif not w.proc.is_alive():  # replaced when it is next given a job
                    index, w.job = w.job, None
                    yield JobResult(index, False, error=f"worker process died (exit code {w.proc.exitcode})")
    finally:
        for w in pool:
            if w.job is not None or not w.proc.is_alive():
                stop(w.proc)
            else:
                w.conn.send(None)
        for w in pool:
            w.proc.join(10.0)
            if w.proc.is_alive():
                stop(w.proc)
