"""LiDAR revolutions simulated ahead in a worker process, so ray casting overlaps with matching and fusion.

In open loop the vessel's path is planned before the run, so revolution k + 1, k + 2, ... can be
ray cast while the run matches and fuses revolution k: the calling process, which otherwise casts
every ray, gets and fuses the revolutions, and the matchers' worker and this one share the other
core. A worker assembles the scenario itself (a spawned process: Embree's scene is not shared) and
casts the revolutions at the times it is given, AHEAD_SCANS at most before they are asked for, so
memory stays flat. A revolution depends on the scenario, its seed and its start time only
(sim.lidar: one random stream per revolution), so the scans are the very ones the calling process
would cast. A closed-loop path depends on the estimators' poses and is cast in step.
"""

from __future__ import annotations

import multiprocessing as mp
import queue
import signal
import time
import traceback

import numpy as np

from riverbench.provenance import peak_rss_mb
from scenarios.pipeline.assembly import assemble
from scenarios.spec.scenario import Scenario
from sim.scan import Scan

AHEAD_SCANS = 4
"""Revolutions cast before they are asked for (a queue bound: enough to ride out one slow revolution, memory stays flat)."""


def _cast(scenario: Scenario, times: np.ndarray, outbox, inbox) -> None:
    """The worker: assemble the scenario, cast the revolution at each time in order until told to stop, then report its
    peak memory."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the caller handles Ctrl-C and stops the worker
    try:
        run = assemble(scenario).vessel_run
        for t in times:
            if not inbox.empty():  # the run ended early (a contact, a failure, Ctrl-C)
                break
            outbox.put(("scan", run.lidar.scan(run.world, run.trajectory, float(t))))
    except (ValueError, RuntimeError, FloatingPointError) as exc:  # what a run records as a failed simulation
        outbox.put(("error", str(exc)))
    except Exception:  # anything else is a bug: its type and line travel with it
        outbox.put(("error", traceback.format_exc(limit=1).strip().splitlines()[-1]))
    inbox.get()
    outbox.put(("rss", peak_rss_mb()))


class ScanAhead:
    """`scan(t)`: the revolution starting at t, cast ahead in a worker; times must be asked for in the order given."""

    def __init__(self, scenario: Scenario, times: np.ndarray) -> None:
        ctx = mp.get_context("spawn")  # never fork a process holding Embree and OpenMP threads
        self._outbox, self._inbox = ctx.Queue(maxsize=AHEAD_SCANS), ctx.Queue()
        self._proc = ctx.Process(target=_cast, args=(scenario, np.asarray(times, dtype=float), self._outbox, self._inbox), daemon=True)
        self._proc.start()
        self.rss_mb = 0.0
        """The worker's peak memory (MB), known once closed."""

    def scan(self, t: float) -> Scan:
        """The next revolution, which must start at t; a failed simulation raises RuntimeError with the worker's reason."""
        kind, payload = self._receive()
        if kind == "error":
            raise RuntimeError(payload)
        if kind != "scan" or payload.stamp != t:
            raise RuntimeError(f"lidar worker: expected the revolution at t={t:.9f} s, got {kind} {getattr(payload, 'stamp', '')}")
        return payload

    def _receive(self) -> tuple[str, object]:
        while True:
            try:
                return self._outbox.get(timeout=1.0)
            except queue.Empty:
                if not self._proc.is_alive():
                    return "error", f"lidar worker died (exit code {self._proc.exitcode})"

    def close(self, wait_s: float = 10.0) -> None:
        """Stop the worker (its peak memory into rss_mb); revolutions cast but never asked for are dropped."""
        if self._proc.is_alive():
            self._inbox.put(None)
            deadline = time.monotonic() + wait_s
            while self._proc.is_alive() and time.monotonic() < deadline:
                try:
                    kind, payload = self._outbox.get(timeout=0.2)
                except queue.Empty:
                    continue
                except Exception:  # a message half-sent by a dying worker
                    break
                if kind == "rss":
                    self.rss_mb = float(payload)
                    break
        self._proc.join(timeout=5.0)
        if self._proc.is_alive():
            self._proc.terminate()

    def __enter__(self) -> ScanAhead:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
