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
import statistics
import time
import xml.etree.ElementTree as ET
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from riverbench import provenance
from riverbench.atomic import atomic_path
from scenarios.batch.workers import raise_terminated, stop
from scenarios.score.regression import Comparison, MetricVerdict
from scenarios.spec.scenario import Scenario


@dataclass(frozen=True)
class Job:
    """One run of the suite: a library name or .toml path, its seed (None: the file's) and --set overrides, its directory name."""

    source: str
    seed: int | None = None
    overrides: tuple[str, ...] = ()
    subdir: str = ""  # below the suite's directory; default the scenario's name

    @property
    def name(self) -> str:
        return Path(self.source).stem

    @property
    def where(self) -> str:
        return self.subdir or self.name


def jobs_for(sources: list[str], seeds: list[int] | None = None, overrides: tuple[str, ...] = ()) -> list[Job]:
    """A job per scenario (seeds None: its own seed, into <name>/) or per scenario and seed (into <name>/seed-<k>/)."""
    if seeds is None:
        return [Job(source, None, overrides) for source in sources]
    return [Job(source, seed, overrides, f"{Path(source).stem}/seed-{seed}") for source in sources for seed in seeds]


@dataclass
class CaseResult:
    """One scenario run of the suite: its run directory, each expectation's outcome, or why it did not finish."""

    name: str
    run_dir: str
    wall_s: float
    expectations: list[dict] = field(default_factory=list)
    error: str = ""
    realtime_factor: float | None = None
    seed: int | None = None
    scenario_hash: str = ""  # Scenario.setup_hash: what ran, expectations left out (a baseline compares on it)

    @property
    def passed(self) -> bool:
        return not self.error and all(e["pass"] for e in self.expectations)

    @property
    def label(self) -> str:
        """The scenario's name, and its seed when the suite ran several."""
        return self.name if self.seed is None else f"{self.name} seed {self.seed}"


def case_scenario(job: Job, fast: bool) -> Scenario:
    """What the suite runs for a job: with --fast the scenario's [fast] variant, or the full scenario when it has none
    (as the library's baseline was measured; `run --fast` and `sweep --fast` refuse such a scenario instead)."""
    from scenarios.spec.library import load

    scenario = load(job.source, set=list(job.overrides), seed=job.seed)
    return scenario.fast_variant() if fast else scenario


def _run_case(index: int, job: Job, fast: bool, out_dir: str, workers: int, results) -> None:
    """Child process: load, run and report back one scenario (never raises)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the suite's to handle; it terminates us
    signal.signal(signal.SIGTERM, raise_terminated)
    start = time.perf_counter()
    try:
        from scenarios.pipeline.runner import run

        scenario = case_scenario(job, fast)
        result = run(scenario, out_dir, workers=workers)
        results.put(
            (
                index,
                CaseResult(
                    scenario.name,
                    str(result.out_dir),
                    time.perf_counter() - start,
                    result.metrics["expectations"],
                    realtime_factor=result.metrics["run"]["realtime_factor"],
                    seed=job.seed,
                    scenario_hash=scenario.setup_hash,
                ),
            )
        )
    except BaseException as exc:  # the suite records any failure of one scenario and goes on
        results.put((index, CaseResult(job.name, out_dir, time.perf_counter() - start, error=f"{type(exc).__name__}: {exc}", seed=job.seed)))


def run_suite(
    jobs: list[Job] | list[str],
    out_dir: Path,
    *,
    workers: int = 2,
    fast: bool = False,
    timeout_s: float = 3600.0,
    on_done: Callable[[CaseResult], None] | None = None,
) -> list[CaseResult]:
    """Run each job (or library name / path) into out_dir/<its directory>/, `workers` at a time, in the given order."""
    ctx = mp.get_context("spawn")
    results = ctx.Queue()
    pending = [(i, job if isinstance(job, Job) else Job(job)) for i, job in enumerate(jobs)]
    running: dict[int, tuple[mp.Process, float, Job]] = {}
    done: dict[int, CaseResult] = {}
    inner_workers = 2 if workers == 1 else 1  # one scenario alone uses both cores
    try:
        while pending or running:
            while pending and len(running) < workers:
                index, job = pending.pop(0)
                proc = ctx.Process(target=_run_case, args=(index, job, fast, str(out_dir / job.where), inner_workers, results), daemon=False)
                proc.start()
                running[index] = (proc, time.perf_counter(), job)
            try:
                index, case = results.get(timeout=0.5)
                if index in running:  # not one already timed out
                    running.pop(index)[0].join()
                    _finish(done, index, case, on_done)
            except queue.Empty:
                pass
            for index, (proc, started, job) in list(running.items()):
                elapsed = time.perf_counter() - started
                if not proc.is_alive() and results.empty():
                    running.pop(index)
                    case = CaseResult(
                        job.name, str(out_dir / job.where), elapsed, error=f"scenario process died (exit code {proc.exitcode})", seed=job.seed
                    )
                    _finish(done, index, case, on_done)
                elif elapsed > timeout_s:
                    stop(proc)
                    running.pop(index)
                    case = CaseResult(job.name, str(out_dir / job.where), elapsed, error=f"timed out after {timeout_s:g} s", seed=job.seed)
                    _finish(done, index, case, on_done)
    finally:
        for proc, _, _ in running.values():
            stop(proc)
    return [done[i] for i in sorted(done)]


def _finish(done: dict, index: int, case: CaseResult, on_done) -> None:
    done[index] = case
    if on_done is not None:
        on_done(case)


def write_summary(cases: list[CaseResult], path: Path, comparison: Comparison | None = None) -> None:
    """suite.json: every case with its expectations (what `riverbench report` reads over a suite) and, against a
    baseline, the comparison (counts, both sides' provenance, every metric that moved)."""
    summary = {
        "provenance": provenance.collect(),
        "cases": [{**asdict(c), "passed": c.passed} for c in cases],
        "baseline_comparison": comparison.as_dict() if comparison is not None else None,
    }
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(summary, indent=2) + "\n")


def write_junit(cases: list[CaseResult], path: Path, comparison: Comparison | None = None) -> None:
    """JUnit XML: one testcase per scenario run and one per expectation, failures with their reason; against a baseline
    also one per scenario and metric family (classname riverbench.<scenario>.baseline), failing on a regression."""
    suite = ET.Element("testsuite", name="riverbench")
    tests = failures = errors = 0
    for case in cases:
        run_case = ET.SubElement(suite, "testcase", classname=f"riverbench.{case.name}", name=_run_name(case), time=f"{case.wall_s:.3f}")
        tests += 1
        if case.error:
            ET.SubElement(run_case, "error", message=case.error).text = case.error
            errors += 1
        for e in case.expectations:
            tc = ET.SubElement(suite, "testcase", classname=f"riverbench.{case.name}", name=_expect_name(case, e["expect"]), time="0")
            tests += 1
            if not e["pass"]:
                ET.SubElement(tc, "failure", message=e["reason"]).text = e["reason"]
                failures += 1
    if comparison is not None:
        for (scenario, family), verdicts in _by_family(comparison).items():
            tc = ET.SubElement(suite, "testcase", classname=f"riverbench.{scenario}.baseline", name=family, time="0")
            tests += 1
            props = ET.SubElement(tc, "properties")
            for v in verdicts:
                if not v.identical:
                    ET.SubElement(props, "property", name=v.metric, value=f"{v.verdict}: {regression_line(v)}")
            bad = [v for v in verdicts if v.verdict == "regressed" and v.gating]
            if bad:
                message = "; ".join(f"{v.metric} {regression_line(v)}" for v in bad)
                ET.SubElement(tc, "failure", message=message).text = "\n".join(f"{v.metric}: {regression_line(v)}" for v in bad)
                failures += 1
            moved = [v for v in verdicts if v.verdict in ("improved", "changed")]
            if moved:
                ET.SubElement(tc, "system-out").text = "\n".join(f"{v.verdict} {v.metric}: {regression_line(v)}" for v in moved)
    suite.set("tests", str(tests))
    suite.set("failures", str(failures))
    suite.set("errors", str(errors))
    with atomic_path(path) as tmp:
        ET.ElementTree(suite).write(tmp, encoding="utf-8", xml_declaration=True)


def _run_name(case: CaseResult) -> str:
    return "run" if case.seed is None else f"run seed {case.seed}"


def _expect_name(case: CaseResult, expect: str) -> str:
    return expect if case.seed is None else f"{expect} (seed {case.seed})"


def _by_family(comparison: Comparison) -> dict[tuple[str, str], list[MetricVerdict]]:
    """The verdicts grouped by scenario and metric family, in order."""
    out: dict[tuple[str, str], list[MetricVerdict]] = {}
    for v in comparison.verdicts:
        out.setdefault((v.scenario, v.family.name), []).append(v)
    return out


def regression_line(v: MetricVerdict) -> str:
    """'baseline 2.41 [2.30..2.57], now 3.10 (+0.69, threshold 0.24)': what a reader needs to judge the verdict."""
    base = [x for x in v.base if x == x]
    now = [x for x in v.now if x == x]
    if not base or not now:
        return f"baseline {_g(base)}, now {_g(now)} (measured on one side only)"
    return (
        f"baseline {_g(base)} [{min(base):.4g}..{max(base):.4g}], now {_g(now)} "
        f"({v.change:+.4g}, threshold {v.threshold:.3g}, seeds {', '.join(map(str, v.seeds))})"
    )


def _g(values: list[float]) -> str:
    return f"{statistics.median(values):.4g}" if values else "none"
