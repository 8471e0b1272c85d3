"""`scenarios.run(scenario, out_dir)` (scenarios.runner.run): stream a scenario through the matchers and estimators under
test, score them against the exact truth and write the run directory.

Streaming: each revolution is simulated, handed to the matchers (in worker processes, so the next
revolution is ray cast while this one is matched), fed to the estimators with the fixes in time
order, reduced to a few numbers and dropped; memory stays flat in scenario length. The directory is
written under a temporary name and renamed at the end: a run that fails or is interrupted leaves
nothing behind and says at which scan and why.
"""

from __future__ import annotations

import json
import math
import os
import resource
import shutil
import tempfile
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path

import numpy as np
import tomli_w

import sim
import worlds
from fusion.verdict import Verdict
from scenarios import files, metrics
from scenarios import windows as win
from scenarios.expectations import Outcome
from scenarios.matcher_pool import MatcherPool, MatcherSetup
from scenarios.record import Recorder, RunRecord, nan_pose
from scenarios.spec import Scenario
from scenarios.stream import ScanEvent, events

RUN_NUMBERS = ("seed", "t_start", "t_end", "sim_s", "wall_s", "realtime_factor", "peak_rss_mb", "scans", "fixes", "workers")
"""The numbers of metrics.json's `run` node (besides scenario, scenario_hash, lanes and failures)."""
LOOKAHEAD_SCANS = 1
"""Scans simulated ahead of the one being matched (the overlap of simulation and matching)."""


class RunFailed(RuntimeError):
    """The run could not go on (the simulation itself failed); nothing was written."""


class RunInterrupted(RuntimeError):
    """Ctrl-C: the run stopped cleanly; nothing was written."""


@dataclass
class RunResult:
    """A finished run: where it is, its metrics tree and each expectation's outcome."""

    scenario: Scenario
    out_dir: Path
    metrics: dict
    outcomes: list[Outcome] = field(default_factory=list)

    @property
    def passed(self) -> bool:
        return all(o.passed for o in self.outcomes)

    @property
    def report(self) -> Path:
        return self.out_dir / "report.html"


def default_out_dir(scenario: Scenario) -> Path:
    """runs/<scenario>-<UTC time>/"""
    return Path("runs") / f"{scenario.name}-{datetime.now(timezone.utc):%Y%m%dT%H%M%SZ}"


def run(
    scenario: Scenario,
    out_dir: str | os.PathLike | None = None,
    *,
    workers: int = 2,
    report: bool = True,
    progress: Callable[[float, float, float, int], None] | None = None,
) -> RunResult:
    """Run `scenario` and write its run directory (default runs/<name>-<UTC time>/).

    workers: processes in use (1: everything in this process; 2, the default: matchers overlap
    with the simulation). report: also write report.md, report.html and plots/. progress, if
    given, is called as progress(t, t_start, t_end, scans) after each event.
    """
    out = Path(out_dir) if out_dir is not None else default_out_dir(scenario)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"output directory {out} exists and is not empty")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        metrics_tree, outcomes = _run_into(scenario, tmp, workers, report, progress)
        os.chmod(tmp, 0o755)  # mkdtemp made it private; a run directory is for everyone to read
        if out.exists():
            out.rmdir()
        os.replace(tmp, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return RunResult(scenario, out, metrics_tree, outcomes)


def _run_into(scenario: Scenario, tmp: Path, workers: int, report: bool, progress) -> tuple[dict, list[Outcome]]:
    wall_start = time.perf_counter()
    world = worlds.load(scenario.world, **scenario.world_params)
    vessel = scenario.vessel.model_dump(exclude={"seed"})
    trajectory = sim.Trajectory(world, seed=scenario.seed, **vessel)
    lidar = sim.HDL32E(seed=scenario.seed, **scenario.lidar.model_dump(exclude={"seed", "rate_hz", "range_noise_m"}),
                       rate_hz=scenario.lidar.rate_hz, range_noise_m=scenario.lidar.range_noise_m)
    receiver = sim.GnssReceiver(seed=scenario.seed, **scenario.gnss.model_dump(exclude={"rate_hz"}), rate_hz=scenario.gnss.rate_hz)
    t_start, t_end = scenario.stretch.times(trajectory)
    feeds = {e.id: e.matcher for e in scenario.estimators}
    refs = {c.id: c.ref for c in [*scenario.matchers, *scenario.estimators]}  # kind or plugin path: failures name it
    recorder = Recorder([m.id for m in scenario.matchers], list(feeds), trajectory.mount)
    estimators, dead = _build_estimators(scenario, recorder, t_start)
    queue: deque = deque()
    scans = 0
    now = t_start

    def feed_estimators(call: Callable[[str, object], object], stamp: float) -> dict:
        out = {}
        for eid, est in estimators.items():
            if eid in dead:
                continue
            try:
                out[eid] = call(eid, est)
            except Exception as exc:  # an estimator that raises fails from this input on; the run goes on
                dead.add(eid)
                recorder.failure("estimator", eid, stamp, f"{refs[eid]}: {type(exc).__name__}: {exc}")
        return out

    def scan_step(eid: str, est, stamp: float, results: dict) -> np.ndarray:
        """Feed one estimator its matcher's result (none for gps_only) and read its pose."""
        if feeds[eid]:
            est.add_match(stamp, results[feeds[eid]])
        return _checked_pose(est.pose)

    def process_scan(event: ScanEvent, results: dict, errors: dict) -> None:
        for mid, why in errors.items():
            recorder.failure("matcher", mid, event.stamp, f"{refs[mid]}: {why}")
        poses = feed_estimators(lambda eid, est: scan_step(eid, est, event.stamp, results), event.stamp)
        recorder.scan(event.stamp, trajectory.pose(event.stamp), results, {eid: poses.get(eid, nan_pose()) for eid in estimators})

    def process_fix(fix, nmea) -> None:
        verdicts = feed_estimators(lambda eid, est: _checked_verdict(est.add_fix(fix)), fix.stamp)
        # a failed estimator raises no alarm: its fixes count as trusted with no statistic
        recorder.fix(fix, {eid: (verdicts[eid].trusted, verdicts[eid].statistic) if eid in verdicts else (True, math.nan)
                           for eid in estimators})
        nmea.write("\r\n".join(fix.nmea()) + "\r\n")

    def drain(pool, nmea, keep_scans: int) -> None:
        while queue and sum(isinstance(e, ScanEvent) for e in queue) > keep_scans:
            event = queue.popleft()
            if isinstance(event, ScanEvent):
                process_scan(event, *pool.collect())
            else:
                process_fix(event.fix, nmea)
        while queue and not isinstance(queue[0], ScanEvent):
            process_fix(queue.popleft().fix, nmea)

    setups = [MatcherSetup(m.id, m.ref, m.params) for m in scenario.matchers]
    with MatcherPool(setups, workers) as pool, open(tmp / "gps.nmea", "w", newline="") as nmea:
        try:
            for event in events(world, trajectory, lidar, receiver, t_start, t_end):
                now = event.stamp
                queue.append(event)
                if isinstance(event, ScanEvent):
                    pool.submit(event.scan)
                    scans += 1
                drain(pool, nmea, LOOKAHEAD_SCANS)
                if progress is not None:
                    progress(now, t_start, t_end, scans)
            drain(pool, nmea, 0)
        except KeyboardInterrupt:
            raise RunInterrupted(f"interrupted at t={now:.1f} s (scan {scans}); nothing written") from None
        except (ValueError, RuntimeError, FloatingPointError) as exc:
            raise RunFailed(f"scan {scans} at t={now:.2f} s: {exc}") from None
        pool.close()
        workers_rss = pool.workers_rss_mb
        lanes = pool.lanes
    rec = recorder.finish([(w.start_s, w.end_s) for w in scenario.gnss.forced_biases])
    wall = time.perf_counter() - wall_start
    run_info = {
        "scenario": scenario.name, "scenario_hash": scenario.hash, "seed": scenario.seed,
        "t_start": t_start, "t_end": t_end, "sim_s": t_end - t_start, "wall_s": wall,
        "realtime_factor": (t_end - t_start) / wall if wall > 0 else math.nan,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0 + workers_rss,
        "scans": len(rec.scan_t), "fixes": len(rec.fixes.t), "workers": len(lanes), "lanes": lanes,
        "failures": rec.failures,
    }
    return _write(scenario, tmp, rec, run_info, 1.0 / receiver.rate_hz, report)


def _build_estimators(scenario: Scenario, recorder: Recorder, t_start: float) -> tuple[dict, set[str]]:
    """Every estimator by id, and the ids of those whose constructor raised (recorded as failed from the start)."""
    estimators, dead = {}, set()
    for spec in scenario.estimators:
        try:
            estimators[spec.id] = spec.build(scenario.seed)
        except Exception as exc:  # a plugin's constructor may raise anything: that estimator fails, the run goes on
            estimators[spec.id] = None
            dead.add(spec.id)
            recorder.failure("estimator", spec.id, t_start, f"{spec.ref}: could not be built: {type(exc).__name__}: {exc}")
    return estimators, dead


def _checked_pose(pose) -> np.ndarray:
    """An estimator's pose as a 4x4 float array, or a TypeError (a plugin's may be anything)."""
    matrix = np.asarray(pose, dtype=float)
    if matrix.shape != (4, 4):
        raise TypeError(f"pose has shape {matrix.shape}, not (4, 4)")
    return matrix


def _checked_verdict(verdict) -> Verdict:
    """What add_fix returned, if it is a fusion Verdict, or a TypeError (a plugin's may be anything)."""
    if not isinstance(verdict, Verdict):
        raise TypeError(f"add_fix returned a {type(verdict).__name__}, not a fusion.Verdict")
    return verdict


def _write(scenario: Scenario, tmp: Path, rec: RunRecord, run_info: dict, fix_period: float, report: bool) -> tuple[dict, list[Outcome]]:
    windows = win.find(rec.fixes, rec.injected, fix_period)
    tree = metrics.compute(rec, windows, run_info)
    safe = metrics.json_safe(tree)
    outcomes = [e.check(safe) for e in scenario.expectations()]
    safe["expectations"] = [o.as_dict() for o in outcomes]
    (tmp / "scenario.toml").write_text(f"# resolved scenario {scenario.hash}: every default filled in; `riverbench run` this file to reproduce the run\n"
                                       + tomli_w.dumps(scenario.resolved()))
    (tmp / "metrics.json").write_text(json.dumps(metrics.json_safe(safe), indent=2) + "\n")
    files.write_tum(tmp / "groundtruth.tum", rec.scan_t, rec.truth)
    for eid, poses in rec.estimates.items():
        files.write_tum(tmp / f"{eid}.tum", rec.scan_t, poses)
    for mid, track in rec.matches.items():
        files.write_tum(tmp / f"{mid}.tum", rec.scan_t, track.pose)
    files.write_gps_csv(tmp / "gps.csv", rec)
    errors = {eid: metrics.horizontal_error(p, rec.truth) for eid, p in rec.estimates.items()}
    files.write_windows_csv(tmp / "windows.csv", windows, rec, errors)
    files.write_scans_csv(tmp / "scans.csv", rec)
    if report:
        from scenarios import report as report_module

        report_module.write(tmp, scenario=scenario)
    return safe, outcomes
