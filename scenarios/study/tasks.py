"""The study's units of work, each run in a worker process (scenarios.batch.workers.run_jobs) from the assembled scenario:
the receiver over every epoch of the stretch, matchers on bursts of consecutive revolutions, and one matcher chained
over a piece of the stretch. Each returns plain arrays (small: never a scan)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, cast

import numpy as np

import matcher as matchers
from matcher.motion import pose_to_xyzrpy
from riverbench.angles import wrap_angle
from scenarios.pipeline.assembly import assemble
from scenarios.pipeline.stream import scan_times
from scenarios.score.record import FixTable, MatcherTrack, Recorder
from scenarios.spec.scenario import Scenario
from sim.magnetic_compass import CompassConfig, MagneticCompass
from sim.scene import Scene

OUTLIER_KEYS = ("outlier_share", "prealign_rejected_share", "inlier_share", "plane_outlier_share")
"""The outlier diagnostics the matchers report in MatchResult.info (pcl6d: outlier_share of its point-to-plane fit,
prealign_rejected_share of its FPFH correspondences when it pre-aligned; gicp: inlier_share, plane_outlier_share)."""


@dataclass
class GnssSample:
    """Every receiver epoch of the stretch: the fixes as a run records them, the true count of satellites seen
    directly (line of sight), the count of satellites used whose direct signal a facade reflection also reaches (the
    truth: code multipath) and the vessel's route station at each epoch."""

    fixes: FixTable
    los: np.ndarray
    station: np.ndarray
    period_s: float
    reflected: np.ndarray | None = None


def gnss(scenario: Scenario) -> GnssSample:
    """The scenario's receiver driven over every epoch of its stretch (its internal filter runs on, as in a run)."""
    stack = assemble(scenario)
    receiver, trajectory, world = stack.receiver, stack.trajectory, stack.vessel_run.world
    recorder = Recorder([], [], stack.trajectory.mount)
    los, reflected = [], []
    times = receiver.epochs(stack.t_end, stack.t_start)
    for t in times:
        fix = receiver.fix(world, trajectory, float(t))
        recorder.fix(fix, {})
        sats = fix.truth.sats if fix.truth is not None else ()
        los.append(sum(s.los for s in sats))
        reflected.append(sum(r.used and s.los and s.bias_m != 0.0 for r, s in zip(fix.sats, sats)))
    fixes = recorder.finish([]).fixes
    station = np.asarray(trajectory.station(np.asarray(times, dtype=float)))
    return GnssSample(fixes, np.asarray(los, dtype=int), station, 1.0 / receiver.rate_hz, np.asarray(reflected, dtype=int))


def bursts(job: tuple[Scenario, list[float], list[bool], int]) -> list[dict]:
    """job = (scenario, burst start times, whether pcl6d registers each burst, revolutions per burst): every matcher
    (fresh for each burst) registers the burst's revolutions in order; a row per registration after the first, with its
    outcome, points, wall time (and the process's CPU time: steadier on a shared machine, all threads counted), error
    against the exact relative lidar motion and outlier diagnostics."""
    scenario, starts, with_pcl6d, n = job
    stack = assemble(scenario)
    lidar, trajectory, world = stack.lidar, stack.trajectory, cast(Scene, stack.vessel_run.world)
    rows = []
    for t0, pcl6d in zip(starts, with_pcl6d):
        scans = [lidar.scan(world, trajectory, float(t0) + k * lidar.revolution_s) for k in range(n)]
        for spec in scenario.matchers:
            if spec.ref == "pcl6d" and not pcl6d:
                continue
            m = matchers.create(spec.ref, **spec.params)
            for k, scan in enumerate(scans):
                cpu = time.process_time()
                r = m.register(scan)
                if k > 0:
                    rows.append({**_row(spec.id, scan.stamp, r, trajectory), "cpu_seconds": time.process_time() - cpu})
    return rows


def _row(mid: str, stamp: float, r, trajectory) -> dict:
    """One registration: outcome, points, seconds, translation and yaw error of an ok match, the outlier diagnostics."""
    err_m = err_deg = math.nan
    ref = r.info.get("ref_stamp")
    if r.ok and ref is not None:
        truth = np.linalg.solve(trajectory.lidar_pose(float(ref)), trajectory.lidar_pose(stamp))
        delta = np.linalg.solve(truth, np.asarray(r.T, dtype=float))
        err_m = float(np.linalg.norm(delta[:3, 3]))
        err_deg = float(abs(math.degrees(pose_to_xyzrpy(delta)[5])))
    row = {
        "matcher": mid,
        "t": float(stamp),
        "ok": bool(r.ok),
        "gated": bool(r.info.get("gated", False)),
        "points": int(r.n_points),
        "seconds": float(r.seconds),
        "error_m": err_m,
        "yaw_error_deg": err_deg,
    }
    row.update({k: float(r.info[k]) for k in OUTLIER_KEYS if isinstance(r.info.get(k), (int, float))})
    return row


@dataclass
class ChainPiece:
    """One piece of the chained odometry: scan times, true and chained base_link poses (chained from the true pose at
    the piece's first scan), and the matcher's per-scan track."""

    t: np.ndarray
    truth: np.ndarray
    track: MatcherTrack


def chain(job: tuple[Scenario, str, int, int, int]) -> ChainPiece:
    """job = (scenario, matcher id, first, last, stride): that matcher registers every stride-th revolution of the
    stretch from index first to last (of those)."""
    scenario, mid, first, last, stride = job
    stack = assemble(scenario)
    lidar, trajectory, world = stack.lidar, stack.trajectory, cast(Scene, stack.vessel_run.world)
    spec = scenario.matcher_spec(mid)
    m = matchers.create(spec.ref, **spec.params)
    recorder = Recorder([mid], [], trajectory.mount)
    for t in scan_times(lidar, stack.t_start, stack.t_end)[::stride][first : last + 1]:
        scan = lidar.scan(world, trajectory, float(t))
        recorder.scan(float(t), trajectory.pose(float(t)), {mid: m.register(scan)}, {})
    rec = recorder.finish([])
    return ChainPiece(rec.scan_t, rec.truth, rec.matches[mid])


COMPASS_PERIOD_S = 1.0
"""The compass is read once a second over the stretch (its error changes slowly: steel passes take tens of seconds)."""


def compass(scenario: Scenario) -> tuple[np.ndarray, np.ndarray]:
    """(times, heading error in rad) of the magnetic compass (sim.magnetic_compass, the scenario's [compass] or its
    defaults) along the stretch."""
    stack = assemble(scenario)
    trajectory = stack.trajectory
    unit = MagneticCompass(stack.world, scenario.compass or CompassConfig(), seed=scenario.seed)
    ts = np.arange(stack.t_start, stack.t_end, COMPASS_PERIOD_S)
    measured = np.array([s.yaw for s in unit.read(trajectory, ts)])
    truth = np.array([math.atan2(p[1, 0], p[0, 0]) for p in trajectory.poses(ts)])
    return ts, wrap_angle(measured - truth)


@dataclass
class Timed:
    """A job's result and what it cost in its worker: wall and CPU seconds (the study's schedule is judged on them)."""

    value: Any
    wall_s: float
    cpu_s: float


def run_task(job: tuple[str, object]) -> Timed:
    """Dispatch one (kind, argument) job in a worker: kind is gnss, bursts, chain or compass."""
    kind, arg = job
    handlers: dict[str, Callable[[Any], object]] = {"gnss": gnss, "bursts": bursts, "chain": chain, "compass": compass}
    wall, cpu = time.perf_counter(), time.process_time()
    value = handlers[kind](arg)
    return Timed(value, time.perf_counter() - wall, time.process_time() - cpu)
