"""Matchers spread over processes so that matching overlaps with simulation on both cores.

Each matcher lives in one lane for the whole run (matchers are stateful). Lane 0 is the calling
process, which also simulates and runs the estimators; lanes 1.. are worker processes fed through
queues (their feeder threads send while the caller keeps simulating). Matchers go greedily to the
least-loaded lane by a rough per-scan cost measured with benchmarks/matchers.py. A matcher whose
constructor raises, that raises or returns anything but a well-formed MatchResult, or whose worker
dies, fails from that scan on; the run goes on. A plugin matcher is imported again in each worker
(spawned processes inherit sys.path), so it must be importable: installed or on PYTHONPATH.
"""

from __future__ import annotations

import multiprocessing as mp
import queue
import signal
import time
import traceback
from collections import deque
from dataclasses import dataclass

import numpy as np

import matcher as matchers_pkg
from matcher.result import MatchResult, checked
from riverbench.provenance import peak_rss_mb
from sim.scan import Scan

COST_MS = {"pcl6d": 8.0, "gicp": 5.0, "kiss_icp": 3.0, "bev3dof": 1.5}
"""Rough median ms per charles_river scan (benchmarks/matchers.py), for placing matchers on lanes."""
CALLER_BASE_MS = 10.0
"""What the calling lane already spends per scan: the fixes and the estimators (8-10 ms a charles_river scan in a
5-minute run's profile; an open-loop run casts its revolutions ahead in another process, a closed loop casts them here
and spends about 12 ms more, which this does not count)."""


@dataclass(frozen=True)
class MatcherSetup:
    """What a lane needs to build one matcher (kind: a matcher name or a plugin 'package.module:Class')."""

    id: str
    kind: str
    params: dict


class _Unbuilt:
    """Stands in for a matcher whose constructor raised: it fails at the first scan, with why."""

    def __init__(self, why: str) -> None:
        self.why = why

    def register(self, scan: Scan) -> MatchResult:
        """Raise why the matcher could not be built."""
        raise RuntimeError(self.why)


def _build(setup: MatcherSetup) -> matchers_pkg.Matcher | _Unbuilt:
    """The matcher `setup` describes, or an _Unbuilt saying why its constructor raised."""
    try:
        return matchers_pkg.create(setup.kind, **setup.params)
    except Exception as exc:  # a plugin's constructor may raise anything: that matcher fails, the run goes on
        return _Unbuilt(f"could not be built: {type(exc).__name__}: {exc}")


class _Lane:
    """Matchers in one process; `register` returns (id, MatchResult, error message or '') per matcher."""

    def __init__(self, setups: list[MatcherSetup]) -> None:
        self.matchers = {s.id: _build(s) for s in setups}
        self.dead: dict[str, str] = {}

    def register(self, scan: Scan) -> list[tuple[str, MatchResult, str]]:
        out = []
        for mid, m in self.matchers.items():
            if mid in self.dead:
                out.append((mid, MatchResult.failure(f"failed earlier: {self.dead[mid]}"), ""))
                continue
            try:
                out.append((mid, checked(m.register(scan)), ""))
            except Exception as exc:  # a matcher that raises (or returns no MatchResult) fails from this scan on
                message = f"{type(exc).__name__}: {exc}"
                self.dead[mid] = message
                out.append((mid, MatchResult.failure(f"raised: {message}"), message))
        return out


def _worker(setups: list[MatcherSetup], inbox, outbox) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the caller handles Ctrl-C and stops the workers
    try:
        lane = _Lane(setups)
    except Exception as exc:
        outbox.put(("error", f"{type(exc).__name__}: {exc}"))
        return
    outbox.put(("ready", None))
    while True:
        item = inbox.get()
        if item is None:
            outbox.put(("rss", peak_rss_mb()))
            return
        stamp, points = item
        try:
            outbox.put(("results", lane.register(Scan(stamp=stamp, points=points))))
        except Exception:
            outbox.put(("error", traceback.format_exc(limit=1).strip().splitlines()[-1]))
            return


class MatcherPool:
    """submit(scan) for every scan in order, then collect() the results of the oldest pending scan."""

    def __init__(self, setups: list[MatcherSetup], workers: int = 2) -> None:
        lanes: list[list[MatcherSetup]] = [[] for _ in range(max(1, min(workers, len(setups) + 1)))]
        load = [CALLER_BASE_MS] + [0.0] * (len(lanes) - 1)
        for s in sorted(setups, key=lambda s: -COST_MS.get(s.kind, 5.0)):
            lane = int(np.argmin(load))
            lanes[lane].append(s)
            load[lane] += COST_MS.get(s.kind, 5.0)
        self.order = [s.id for s in setups]
        self.lanes = [[s.id for s in lane] for lane in lanes if lane or lane is lanes[0]]
        """Matcher ids per lane (lane 0: the calling process)."""
        self.local = _Lane(lanes[0])
        self.workers_rss_mb = 0.0
        self._pending: deque[Scan] = deque()
        self._procs = []
        ctx = mp.get_context("spawn")  # never fork a process holding Embree and OpenMP threads
        for lane in lanes[1:]:
            if not lane:
                continue
            inbox, outbox = ctx.Queue(), ctx.Queue()
            proc = ctx.Process(target=_worker, args=(lane, inbox, outbox), daemon=True)
            proc.start()
            self._procs.append((proc, inbox, outbox, [s.id for s in lane], {"dead": ""}))
        for proc, _, outbox, ids, _state in self._procs:
            payload = self._receive(proc, outbox, "ready")
            if payload is not None:
                self.close()
                raise RuntimeError(
                    f"matchers {', '.join(ids)}: {payload} (a script that runs scenarios with workers > 1 needs `if __name__ == '__main__':`)"
                )

    def submit(self, scan: Scan) -> None:
        for _proc, inbox, _, _, state in self._procs:
            if not state["dead"]:
                inbox.put((scan.stamp, scan.points))
        self._pending.append(scan)

    def collect(self) -> tuple[dict[str, MatchResult], dict[str, str]]:
        """Results of the oldest submitted scan by matcher id, and the matchers that failed on it (id -> why)."""
        scan = self._pending.popleft()
        results, errors = {}, {}
        for mid, result, error in self.local.register(scan):
            results[mid] = result
            if error:
                errors[mid] = error
        for proc, _, outbox, ids, state in self._procs:
            if not state["dead"]:
                payload = self._receive(proc, outbox, "results")
                if isinstance(payload, str):
                    state["dead"] = payload
                    errors.update({mid: payload for mid in ids})
                else:
                    for mid, result, error in payload:
                        results[mid] = result
                        if error:
                            errors[mid] = error
            if state["dead"]:
                for mid in ids:
                    results.setdefault(mid, MatchResult.failure(f"worker failed: {state['dead']}"))
        return {mid: results[mid] for mid in self.order}, errors

    @staticmethod
    def _receive(proc, outbox, expected: str):
        """The worker's `expected` message payload, or a string saying why there is none (it raised or died)."""
        while True:
            try:
                kind, payload = outbox.get(timeout=1.0)
            except queue.Empty:
                if not proc.is_alive():
                    return f"worker process died (exit code {proc.exitcode})"
                continue
            return payload if kind == expected else f"worker error: {payload}"

    def close(self) -> None:
        """Stop the workers; their peak memory is added to workers_rss_mb."""
        for proc, inbox, outbox, _, state in self._procs:
            if proc.is_alive() and not state["dead"]:
                inbox.put(None)
                self.workers_rss_mb += self._final_rss(proc, outbox)
            proc.join(timeout=5.0)
            if proc.is_alive():
                proc.terminate()
            inbox.cancel_join_thread()  # scans a killed worker never read must not hold this process's exit
        self._procs = []

    @staticmethod
    def _final_rss(proc, outbox, wait_s: float = 10.0) -> float:
        """The stopping worker's peak memory, skipping results nobody collected; 0 if it dies first (a SIGTERM to the
        whole process group ends it as the caller unwinds: no waiting wait_s for an answer that cannot come)."""
        deadline = time.monotonic() + wait_s
        while time.monotonic() < deadline:
            try:
                kind, payload = outbox.get(timeout=0.2)
            except queue.Empty:
                if not proc.is_alive():
                    return 0.0
                continue
            except Exception:  # a message half-sent by a dying worker
                return 0.0
            if kind == "rss":
                return payload
        return 0.0

    def __enter__(self) -> MatcherPool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
