"""`riverbench study`: measure the field study's findings on the charles_river route and write the study directory.

Two rounds of jobs on worker processes (scenarios.batch.workers): the receiver over every epoch and the matchers on
bursts of revolutions, then the chained odometry of the fastest adequate matcher (its pieces in parallel) and the compass.
The directory (report.md, report.html, plots/*.png, study.json) is written under a temporary name and renamed at the
end: a study that fails or is interrupted (Ctrl-C, SIGTERM) leaves nothing behind.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from riverbench import provenance
from scenarios.batch.workers import run_jobs
from scenarios.pipeline import external
from scenarios.pipeline.assembly import assemble
from scenarios.pipeline.matcher_pool import COST_MS
from scenarios.pipeline.stream import scan_times
from scenarios.score.metrics import json_safe
from scenarios.study import causes, components, gnss_findings, matcher_findings, report
from scenarios.study.components import Component
from scenarios.study.findings import CITATION, FINDINGS
from scenarios.study.plan import MATCHERS, SCENARIO, StudyPlan, burst_starts, chain_pieces, component_scenario, study_scenario
from scenarios.study.setups import FIELD_METHOD1_ID, SETUP_NAMES, SETUPS, setup_method1
from scenarios.study.tasks import GnssSample, Timed, run_task
from scenarios.study.verdicts import BY_MATCHER, RULES, headline, verdict

Progress = Callable[[int, int, str], None]
"""progress(jobs done, jobs in all, what finished)."""


@dataclass
class Samples:
    """What the jobs measured, for the plots: the receiver's fixes, the burst registrations, the world's structures."""

    gnss: GnssSample
    rows: list[dict]
    structures: list[dict]


def default_out_dir() -> Path:
    """runs/study-<UTC time>/"""
    return Path("runs") / f"study-{datetime.now(UTC):%Y%m%dT%H%M%SZ}"


def run_study(
    out_dir: str | os.PathLike | None = None,
    *,
    seed: int | None = None,
    stretch_m: tuple[float, float] | None = None,
    plan: StudyPlan | None = None,
    progress: Progress | None = None,
    setups: tuple[str, ...] = SETUP_NAMES,
    commands: list[Component] | None = None,
    command_findings: tuple[str, ...] | None = None,
    overrides: list[str] | None = None,
) -> tuple[Path, dict]:
    """Measure every finding under each of `setups` (scenarios.study.setups: the bench's, the field study's; stretch_m:
    route stations, default the whole route) and write the study directory (default runs/study-<UTC time>/); returns it
    and the study.json tree. `commands`: command components (scenarios.study.components.from_scenario) scored in the
    findings they apply to (`command_findings`: only these), beside the built-ins; `overrides`: `--set key=value`
    assignments on the study's scenario under every setup (plan.study_scenario), stated in the report. An out_dir that exists and is not
    empty is a ValueError, as is a stretch off the route, an unknown setup or a command whose executable is missing."""
    plan = plan or StudyPlan()
    unknown = [name for name in setups if name not in SETUPS]
    if unknown or not setups:
        raise ValueError(f"study setups {list(setups)}: give one or more of {', '.join(SETUP_NAMES)}")
    field = SETUPS["field"].method1 if "field" in setups else None
    scenario = study_scenario(seed, stretch_m, field_method1=field, overrides=overrides)
    receivers = {name: study_scenario(seed, stretch_m, receiver=SETUPS[name].receiver, overrides=overrides) for name in setups}
    out = Path(out_dir) if out_dir is not None else default_out_dir()
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"output directory {out} exists and is not empty")
    runs = component_runs(commands or [], setups, seed, stretch_m, overrides)
    for _, run_scenario in runs.values():
        external.check(run_scenario)  # a missing executable: one line before any work
    stack = assemble(scenario)  # checks the stretch before any work
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        tree = _measure_into(tmp, scenario, receivers, stack, plan, progress, runs, command_findings, list(overrides or []))
        os.chmod(tmp, 0o755)  # mkdtemp made it private; a study directory is for everyone to read
        if out.exists():
            out.rmdir()
        os.replace(tmp, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out, tree


def _jobs(jobs: list[tuple[str, object]], workers: int, total: int, progress: Progress | None, costs: list[dict]) -> list:
    """Run the jobs on `workers` processes; their results in job order (a failed job is a RuntimeError naming it).
    Each job's kind, wall and CPU seconds are appended to `costs` as it finishes (so it counts the jobs done)."""
    results: list = [None] * len(jobs)

    def finished(index: int, timed: Timed) -> None:
        results[index] = timed.value
        costs.append({"kind": jobs[index][0], "wall_s": timed.wall_s, "cpu_s": timed.cpu_s})
        if progress is not None:
            progress(len(costs), total, jobs[index][0])

    if workers == 1:  # in this process: no worker to start (a short stretch, a test)
        for i, job in enumerate(jobs):
            finished(i, run_task(job))
        return results
    for r in run_jobs(run_task, jobs, workers):
        if not r.ok:
            raise RuntimeError(f"study: the {jobs[r.index][0]} job failed: {r.error}")
        finished(r.index, r.value)
    return results


def chain_matcher(rates: dict, plan: StudyPlan) -> str:
    """The fastest matcher (by the bench's nominal cost per scan, scenarios.pipeline.matcher_pool.COST_MS) whose burst
    success is at least plan.chain_adequate_success; else the most successful."""
    by_cost = sorted(rates, key=lambda m: COST_MS.get(m, 5.0))
    adequate = [m for m in by_cost if (rates[m]["success"] or 0.0) >= plan.chain_adequate_success]
    return adequate[0] if adequate else max(by_cost, key=lambda m: np.nan_to_num(rates[m]["success"]))


def component_runs(
    commands: list[Component], setups: tuple[str, ...], seed: int | None, stretch_m, overrides: list[str] | None = None
) -> dict[str, tuple[list[Component], object]]:
    """The runs of the command components, by setup: the matchers under the first setup only (the setups differ in the
    receiver alone), the estimators under each; (their components, the scenario that runs them)."""
    out = {}
    for i, name in enumerate(setups):
        mine = [c for c in commands if c.section == "estimators" or i == 0]
        if mine:
            out[name] = (mine, component_scenario(seed, stretch_m, SETUPS[name].receiver, [(c.section, c.spec) for c in mine], overrides))
    return out


def _measure_into(
    tmp: Path,
    scenario,
    receivers: dict,
    stack,
    plan: StudyPlan,
    progress: Progress | None,
    runs: dict,
    keys: tuple[str, ...] | None,
    overrides: list[str],
) -> dict:
    """Both rounds of jobs, the command components' runs, every setup's findings and the study directory's files; the
    study.json tree (its scenario node names the `--set` overrides the study ran under)."""
    wall_start = time.perf_counter()
    lidar = stack.lidar
    setups = list(receivers)
    starts = burst_starts(stack.t_start, stack.t_end, lidar.revolution_s, plan)
    pcl6d = (np.arange(len(starts)) % plan.pcl6d_every) == 0
    chunks = [c for c in np.array_split(np.arange(len(starts)), 3 * plan.workers) if len(c)]
    round1 = [("gnss", receivers[name]) for name in setups]
    round1 += [("bursts", (scenario, starts[c].tolist(), pcl6d[c].tolist(), plan.burst_scans)) for c in chunks]
    n_scans = len(scan_times(lidar, stack.t_start, stack.t_end)[:: plan.chain_stride])
    pieces = chain_pieces(n_scans, plan.chain_segments)
    total = len(round1) + len(pieces) + 1 + len(runs)
    costs: list[dict] = []
    first = _jobs(round1, plan.workers, total, progress, costs)
    gnss = dict(zip(setups, first[: len(setups)]))
    rows = [row for chunk in first[len(setups) :] for row in chunk]
    structures = stack.world.params.get("structures", [])
    measured = {name: _measure_setup(name, gnss[name], rows, structures, plan) for name in setups}
    tilt = matcher_findings.tilt_change(stack.trajectory, starts, lidar.revolution_s)
    for name in setups:
        measured[name]["f"]["tilt_change_deg"] = tilt  # the vessel's motion, the same under both setups
    mid = chain_matcher(measured[setups[0]]["e"], plan)
    round2 = [("chain", (scenario, mid, a, b, plan.chain_stride)) for a, b in pieces] + [("compass", scenario)]
    round1_wall_s = time.perf_counter() - wall_start
    second = _jobs(round2, plan.workers, total, progress, costs)
    compass_t, compass_error = second[-1]
    h = matcher_findings.yaw_drift(mid, second[:-1], compass_t, compass_error)
    by_setup = {}
    for name in setups:
        measured[name]["h"] = h  # the chain and the compass are the same under both setups
        by_setup[name] = _judged(name, measured[name])
    commands = _commands(tmp, runs, measured, gnss, stack, structures, plan, keys, (compass_t, compass_error), progress, total, costs)
    findings = {}
    for x in FINDINGS:
        node = by_setup[setups[0]][x.key]
        findings[x.key] = {
            "title": x.title,
            "claim": x.claim,
            "study": x.figures,
            **node,
            "setups": {name: by_setup[name][x.key] for name in setups},
        }
        mine = {cid: node["findings"][x.key] for cid, node in commands.items() if x.key in node["findings"]}
        if mine:
            findings[x.key]["components"] = mine
    tree = {
        "provenance": provenance.collect(),
        "citation": CITATION,
        "scenario": {
            "name": SCENARIO,
            "seed": scenario.seed,
            "hash": scenario.hash,
            "t_start": stack.t_start,
            "t_end": stack.t_end,
            "overrides": overrides,
        },
        "plan": {**plan.as_dict(), "bursts": len(starts), "chain_scans": n_scans},
        "setups": {name: asdict(SETUPS[name]) for name in setups},
        "findings": findings,
    }
    if commands:
        tree["components"] = {
            cid: {k: v for k, v in node.items() if k != "findings"} | {"findings": list(node["findings"])} for cid, node in commands.items()
        }
    tree["run"] = {"measure_wall_s": time.perf_counter() - wall_start, "round1_wall_s": round1_wall_s, "workers": plan.workers, "jobs": costs}
    tree = json_safe(tree)
    report.write(tmp, tree, Samples(gnss[setups[0]], _plotted_rows(rows, setups), structures))
    (tmp / "study.json").write_text(json.dumps(tree, indent=2) + "\n")
    return tree


def _commands(tmp: Path, runs: dict, measured: dict, gnss: dict, stack, structures, plan, keys, compass, progress, total, costs) -> dict:
    """Run the command components (components/<setup>/ of the study directory, one run per setup) and judge each in the
    findings it applies to: {id: {section, command, recording, runs: {setup: summary}, findings: {key: {setup: node}}}}."""
    by_key = {x.key: x for x in FINDINGS}
    band = by_key["f"].figures["points_band"]
    out: dict = {}
    for name, (mine, run_scenario) in runs.items():
        counter = components.PointCounter()
        wall, cpu = time.perf_counter(), time.process_time()
        result = run_scenario_dir(run_scenario, tmp / "components" / name, plan.workers, counter)
        costs.append({"kind": "components", "wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu})
        if progress is not None:
            progress(len(costs), total, "components")
        for c in mine:
            wanted = tuple(k for k in c.findings if keys is None or k in keys)
            s = components.scored(result.out_dir, run_scenario, result.metrics, c, counter.points)
            node = out.setdefault(
                c.id,
                {"section": c.section, "command": c.spec.command, "recording": c.spec.recording, "runs": {}, "findings": {k: {} for k in wanted}},
            )
            node["runs"][name] = components.summary(s) | {"run_dir": f"components/{name}"}
            if c.section == "matchers":
                m = components.measure_matcher(s, c.id, wanted, stack.trajectory, band, compass)
                judged_in = {n: m for n in measured}  # the scans are the same under every setup; e's Method 1 is each setup's
            else:
                judged_in = {name: components.measure_estimator(s, gnss[name], wanted, stack.trajectory, structures, plan.post_outage_fixes)}
            for setup, m in judged_in.items():
                for k in wanted:
                    if s.node.get("failed"):
                        node["findings"][k][setup] = {
                            "verdict": "unmeasured",
                            "headline": f"failed: {s.node.get('reason', '')}",
                            "checks": [],
                            "measured": {},
                        }
                    else:
                        node["findings"][k][setup] = components.judged(k, by_key[k], m[k], measured[setup]["e"])
    return out


def run_scenario_dir(scenario, out: Path, workers: int, observer):
    """scenarios.run of a command components' scenario (no report: metrics.json and the trajectories)."""
    from scenarios.pipeline.runner import run

    return run(scenario, out, workers=workers, report=False, observer=observer)


def _as_method1(rows: list[dict], setup: str) -> list[dict]:
    """The burst rows as the setup sees them: its Method 1's rows named pcl6d, the other setup's Method 1 left out."""
    ours = FIELD_METHOD1_ID if setup == "field" else "pcl6d"
    out = []
    for row in rows:
        if row["matcher"] in ("pcl6d", FIELD_METHOD1_ID):
            if row["matcher"] != ours:
                continue
            row = {**row, "matcher": "pcl6d"}
        out.append(row)
    return out


def _plotted_rows(rows: list[dict], setups: list[str]) -> list[dict]:
    """The burst rows the figures show: the first setup's (its Method 1 named pcl6d) and each other setup's Method 1
    beside them, named 'pcl6d (<setup>)' (setups.setup_method1)."""
    out = _as_method1(rows, setups[0])
    for other in setups[1:]:
        out += [{**row, "matcher": setup_method1(other)} for row in _as_method1(rows, other) if row["matcher"] == "pcl6d"]
    return out


def _measure_setup(name: str, gnss: GnssSample, rows: list[dict], structures: list[dict], plan: StudyPlan) -> dict:
    """Findings a-g measured under one setup: its receiver's fixes (a-d) and the burst rows with its Method 1 (e-g)."""
    measured = gnss_findings.measure(gnss, structures, plan.post_outage_fixes)
    mine = _as_method1(rows, name)
    f = {x.key: x for x in FINDINGS}
    measured["e"] = matcher_findings.rates(mine, list(MATCHERS))
    measured["f"] = matcher_findings.success_curve(mine, list(MATCHERS), f["f"].figures["points_band"])
    measured["g"] = matcher_findings.outliers(mine, list(MATCHERS))
    return measured


def _judged(setup: str, measured: dict) -> dict:
    """Each finding's verdict, headline, cause, checks and measurements under one setup."""
    out = {}
    for x in FINDINGS:
        judged = {"judged": SETUPS[setup].judged_matchers} if x.key in BY_MATCHER else {}
        checks = RULES[x.key](measured[x.key], x, **judged)
        v = verdict(checks)
        out[x.key] = {
            "verdict": v,
            "headline": headline(x.key, measured[x.key]),
            "cause": causes.cause(x.key, setup, v, measured[x.key], measured["f"].get("tilt_change_deg")),
            "checks": [c.as_dict() for c in checks],
            "measured": measured[x.key],
        }
    return out
