"""`scenarios.run(scenario, out_dir)` (scenarios.pipeline.runner.run): stream a scenario through the matchers and estimators under
test, score them against the exact truth and write the run directory.

Streaming: each revolution is simulated, handed to the matchers (in worker processes, so the next
revolution is ray cast while this one is matched), fed to the estimators with the fixes in time
order, reduced to a few numbers and dropped; memory stays flat in scenario length. The directory is
written under a temporary name and renamed at the end: a run that fails or is interrupted leaves
nothing behind and says at which scan and why. An observer (the live view, scenarios.view) can watch
the run as it streams; without one the run does no extra work.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
import time
from collections.abc import Callable
from contextlib import nullcontext
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import tomli_w

from riverbench import provenance
from riverbench.provenance import peak_rss_mb
from riverbench.unixtime import unix_ns
from scenarios.pipeline import external, files
from scenarios.pipeline.assembly import assemble, matcher_setups
from scenarios.pipeline.feed import LOOKAHEAD_SCANS, PIPELINED_SCANS, Feed, RunFailed, RunInterrupted, nmea_writer  # noqa: F401 (RunFailed, RunInterrupted: part of this module's API)
from scenarios.pipeline.matcher_pool import MatcherPool
from scenarios.pipeline.observer import RunObserver
from scenarios.pipeline.scan_ahead import ScanAhead
from scenarios.pipeline.stream import scan_times
from scenarios.pipeline.traffic_log import TrafficLog
from scenarios.score import metrics, units, vessel_log
from scenarios.score import windows as win
from scenarios.score.expectations import Outcome
from scenarios.score.record import RunRecord
from scenarios.spec.scenario import Scenario
from sim.scan import Scan

RUN_NUMBERS = ("seed", "t_start", "t_end", "sim_s", "wall_s", "realtime_factor", "peak_rss_mb", "scans", "fixes", "workers")
"""The numbers of metrics.json's `run` node (besides scenario, scenario_hash, lanes and failures)."""


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
    return Path("runs") / f"{scenario.name}-{datetime.now(UTC):%Y%m%dT%H%M%SZ}"


def run(
    scenario: Scenario,
    out_dir: str | os.PathLike | None = None,
    *,
    workers: int = 2,
    report: bool = True,
    progress: Callable[[float, float, float, int], None] | None = None,
    observer: RunObserver | None = None,
) -> RunResult:
    """Run `scenario` and write its run directory (default runs/<name>-<UTC time>/).

    workers: cores in use (1: everything in this process; 2, the default: the matchers in a worker
    process and, in open loop, the LiDAR cast ahead in another (scenarios.pipeline.scan_ahead), so
    casting, matching and fusion overlap on both cores). report: also write report.md, report.html and plots/. progress, if
    given, is called as progress(t, t_start, t_end, scans) after each event. observer, if given,
    sees the run's world, each scan and fix, and its end (scenarios.pipeline.observer).
    """
    out = Path(out_dir) if out_dir is not None else default_out_dir(scenario)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ValueError(f"output directory {out} exists and is not empty")
    external.check(scenario)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
    try:
        metrics_tree, outcomes = _run_into(scenario, tmp, workers, report, progress, observer)
        if observer is not None:
            observer.close(keep=True)  # before the rename: what it writes into the run directory is complete
        os.chmod(tmp, 0o755)  # mkdtemp made it private; a run directory is for everyone to read
        if out.exists():
            out.rmdir()
        os.replace(tmp, out)
    finally:
        if observer is not None:
            observer.close(keep=False)  # a no-op after close(keep=True)
        shutil.rmtree(tmp, ignore_errors=True)
    return RunResult(scenario, out, metrics_tree, outcomes)


def _run_into(scenario: Scenario, tmp: Path, workers: int, report: bool, progress, observer: RunObserver | None) -> tuple[dict, list[Outcome]]:
    recorded = external.recordings(scenario)  # the command components' recordings: cached, or written now
    wall_start = time.perf_counter()
    stack = assemble(scenario)
    if observer is not None:
        observer.begin(stack, tmp)
    lidar, receiver, vessel_run, t_start, t_end = stack.lidar, stack.receiver, stack.vessel_run, stack.t_start, stack.t_end
    trajectory = vessel_run.trajectory
    traffic_log = TrafficLog(vessel_run.world)
    recorder = stack.recorder()
    setups = matcher_setups(scenario)
    open_loop = vessel_run.loop is None  # else the path, hence the next scan, depends on the fused pose
    lookahead = PIPELINED_SCANS if open_loop else LOOKAHEAD_SCANS
    with MatcherPool(setups, workers) as pool, open(tmp / "gps.nmea", "w", newline="") as nmea:
        feed = Feed(
            scenario,
            pool,
            recorder,
            trajectory.pose,
            t_start,
            nmea_writer(nmea, lambda event: event.fix.nmea()),
            observer=observer,
            lookahead_scans=lookahead,
        )
        points_read = bool(setups) or feed.maps_scans or observer is not None or bool(traffic_log.traffic)
        ahead = ScanAhead(scenario, scan_times(lidar, t_start, t_end)) if workers > 1 and open_loop and points_read else None
        # nothing reads a revolution's points (no matcher, no scan-mapping monitor, no view, no movers to count): the
        # scans are stamps alone, as many as the LiDAR makes (in closed loop too), and the run costs what the receiver,
        # the filters and the vessel cost
        cast = ahead.scan if ahead else (None if points_read else Scan.empty)
        with ahead or nullcontext():
            feed.drive(
                traffic_log.tap(vessel_run.events(feed, cast)),
                lambda event: progress is not None and progress(event.stamp, t_start, t_end, feed.scans),
                (ValueError, RuntimeError, FloatingPointError),
            )
        pool.close()
        lanes = pool.lanes
    workers_rss = pool.workers_rss_mb + (ahead.rss_mb if ahead else 0.0)
    rec = recorder.finish([(w.start_s, w.end_s) for w in scenario.gnss.forced_biases])
    wall = time.perf_counter() - wall_start
    t_last = float(rec.scan_t[-1]) + lidar.revolution_s if len(rec.scan_t) else t_start
    sim_s = t_last - t_start
    run_info = {
        "scenario": scenario.name,
        "scenario_hash": scenario.hash,
        "seed": scenario.seed,
        "t_start": t_start,
        "t_end": t_last,
        "sim_s": sim_s,
        "wall_s": wall,
        "realtime_factor": sim_s / wall if wall > 0 else math.nan,
        "peak_rss_mb": peak_rss_mb() + workers_rss,
        "scans": len(rec.scan_t),
        "fixes": len(rec.fixes.t),
        "workers": len(lanes) + (ahead is not None),
        "lanes": lanes,
        "failures": rec.failures,
    }
    if traffic_log.traffic:
        run_info["mover_points"] = traffic_log.metrics()
        files.write_movers_csv(tmp / "movers.csv", traffic_log)
    vessel_node = vessel_log.metrics(vessel_run.watch.log, scenario.control.clearance_threshold_m, lidar.revolution_s)
    files.write_vessel_csv(tmp / "vessel.csv", vessel_run.watch.log)
    return _write(scenario, tmp, rec, run_info, vessel_node, 1.0 / receiver.rate_hz, report, recorded)


def _write(
    scenario: Scenario, tmp: Path, rec: RunRecord, run_info: dict, vessel: dict, fix_period: float, report: bool, recorded: dict
) -> tuple[dict, list[Outcome]]:
    """Score the run, run and score its command components (`recorded`: their recordings by format), judge the
    expectations and goals and write every file."""
    windows = win.find(rec.fixes, rec.injected, fix_period)
    tree = metrics.compute(rec, windows, run_info, vessel, scenario.integrity.alert_limit_m)
    safe = units.rounded(metrics.json_safe(tree))  # expectations judge the numbers metrics.json shows
    _write_files(scenario, tmp, rec, windows)
    if scenario.commands:
        safe = external.score_into(scenario, tmp, safe, recorded)
    outcomes = [e.check(safe) for e in scenario.expectations()]
    safe["expectations"] = [o.as_dict() for o in outcomes]
    safe["goals"] = [o.as_goal() for o in (g.check(safe) for g in scenario.goal_checks())]
    safe = {"provenance": provenance.collect(), **safe, "units": units.block()}
    (tmp / "metrics.json").write_text(json.dumps(metrics.json_safe(safe), indent=2) + "\n")
    if report:
        from scenarios.report import run_report as report_module

        report_module.write(tmp, scenario=scenario)
    return safe, outcomes


def _write_files(scenario: Scenario, tmp: Path, rec: RunRecord, windows: list[win.Window]) -> None:
    """The run directory's files besides metrics.json and the report."""
    (tmp / "scenario.toml").write_text(
        f"# resolved scenario {scenario.hash}: every default filled in; `riverbench run` this file to reproduce the run\n"
        + tomli_w.dumps(scenario.resolved())
    )
    zero = unix_ns(scenario.gnss.epoch_utc)  # UNIX time of scenario time 0 (scenarios.pipeline.files: time, height)
    files.write_tum(tmp / "groundtruth.tum", rec.scan_t, files.waterline(rec.truth), zero)
    for eid, poses in rec.estimates.items():
        files.write_tum(tmp / f"{eid}.tum", rec.scan_t, files.waterline(poses), zero)
    for mid, track in rec.matches.items():
        files.write_tum(tmp / f"{mid}.tum", rec.scan_t, files.waterline(track.pose), zero)
    files.write_gps_csv(tmp / "gps.csv", rec)
    errors = {eid: metrics.horizontal_error(p, rec.truth) for eid, p in rec.estimates.items()}
    files.write_windows_csv(tmp / "windows.csv", windows, rec, errors)
    files.write_scans_csv(tmp / "scans.csv", rec)
