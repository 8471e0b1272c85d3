"""`riverbench suite`: run library scenarios as a regression suite on a local process pool.

Each scenario runs in its own process (a crash or a time-out is that scenario's failure, with its
reason; the suite goes on); every expectation is checked; the result is a table, suite.json and,
on request, JUnit XML with one testcase per scenario run and per expectation.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import queue
import signal
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from scenarios.atomic import atomic_path
from scenarios.workers import raise_terminated, stop


@dataclass
class CaseResult:
    """One scenario of the suite: its run directory, each expectation's outcome, or why it did not finish."""

    name: str
    run_dir: str
    wall_s: float
    expectations: list[dict] = field(default_factory=list)
    error: str = ""
    realtime_factor: float | None = None

    @property
    def passed(self) -> bool:
        return not self.error and all(e["pass"] for e in self.expectations)


def _run_case(index: int, source: str, fast: bool, out_dir: str, workers: int, results) -> None:
    """Child process: load, run and report back one scenario (never raises)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the suite's to handle; it terminates us
    signal.signal(signal.SIGTERM, raise_terminated)
    start = time.perf_counter()
    try:
        from scenarios.library import load
        from scenarios.runner import run

        scenario = load(source)
        if fast:
            scenario = scenario.fast_variant()
        result = run(scenario, out_dir, workers=workers)
        results.put((index, CaseResult(scenario.name, str(result.out_dir), time.perf_counter() - start,
                                       result.metrics["expectations"], realtime_factor=result.metrics["run"]["realtime_factor"])))
    except BaseException as exc:  # the suite records any failure of one scenario and goes on
        results.put((index, CaseResult(Path(source).stem, out_dir, time.perf_counter() - start, error=f"{type(exc).__name__}: {exc}")))


def run_suite(
    sources: list[str],
    out_dir: Path,
    *,
    workers: int = 2,
    fast: bool = False,
    timeout_s: float = 3600.0,
    on_done: Callable[[CaseResult], None] | None = None,
) -> list[CaseResult]:
    """Run each scenario (library name or path) into out_dir/<name>/, `workers` at a time, in the given order."""
    ctx = mp.get_context("spawn")
    results = ctx.Queue()
    pending = list(enumerate(sources))
    running: dict[int, tuple[mp.Process, float, str]] = {}
    done: dict[int, CaseResult] = {}
    inner_workers = 2 if workers == 1 else 1  # one scenario alone uses both cores
    try:
        while pending or running:
            while pending and len(running) < workers:
                index, source = pending.pop(0)
                case_dir = out_dir / Path(source).stem
                proc = ctx.Process(target=_run_case, args=(index, source, fast, str(case_dir), inner_workers, results), daemon=False)
                proc.start()
                running[index] = (proc, time.perf_counter(), source)
            try:
                index, case = results.get(timeout=0.5)
                if index in running:  # not one already timed out
                    running.pop(index)[0].join()
                    _finish(done, index, case, on_done)
            except queue.Empty:
                pass
            for index, (proc, started, source) in list(running.items()):
                elapsed = time.perf_counter() - started
                if not proc.is_alive() and results.empty():
                    running.pop(index)
                    case = CaseResult(Path(source).stem, str(out_dir / Path(source).stem), elapsed,
                                      error=f"scenario process died (exit code {proc.exitcode})")
                    _finish(done, index, case, on_done)
                elif elapsed > timeout_s:
                    stop(proc)
                    running.pop(index)
                    case = CaseResult(Path(source).stem, str(out_dir / Path(source).stem), elapsed, error=f"timed out after {timeout_s:g} s")
                    _finish(done, index, case, on_done)
    finally:
        for proc, _, _ in running.values():
            stop(proc)
    return [done[i] for i in sorted(done)]


def _finish(done: dict, index: int, case: CaseResult, on_done) -> None:
    done[index] = case
    if on_done is not None:
        on_done(case)


def write_summary(cases: list[CaseResult], path: Path) -> None:
    """suite.json: every case with its expectations (what `riverbench report` reads over a suite)."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps([{**asdict(c), "passed": c.passed} for c in cases], indent=2) + "\n")


def write_junit(cases: list[CaseResult], path: Path) -> None:
    """JUnit XML: one testcase per scenario run and one per expectation, failures with their reason."""
    suite = ET.Element("testsuite", name="riverbench")
    tests = failures = errors = 0
    for case in cases:
        run_case = ET.SubElement(suite, "testcase", classname=f"riverbench.{case.name}", name="run", time=f"{case.wall_s:.3f}")
        tests += 1
        if case.error:
            ET.SubElement(run_case, "error", message=case.error).text = case.error
            errors += 1
        for e in case.expectations:
            tc = ET.SubElement(suite, "testcase", classname=f"riverbench.{case.name}", name=e["expect"], time="0")
            tests += 1
            if not e["pass"]:
                ET.SubElement(tc, "failure", message=e["reason"]).text = e["reason"]
                failures += 1
    suite.set("tests", str(tests))
    suite.set("failures", str(failures))
    suite.set("errors", str(errors))
    with atomic_path(path) as tmp:
        ET.ElementTree(suite).write(tmp, encoding="utf-8", xml_declaration=True)
