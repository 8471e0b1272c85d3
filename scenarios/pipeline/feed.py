"""The streaming loop of a run: scans and fixes in time order through the scenario's matchers and estimators into a Recorder.

`scenarios.run` feeds it simulated events, `scenarios.replay` recorded ones. Each scan goes to
every matcher (a MatcherPool, so the next scans can be read or simulated while one is matched,
LOOKAHEAD_SCANS or PIPELINED_SCANS ahead), then in time order each estimator gets
`add_match(stamp, result)` of its own matcher and gives its pose; each fix goes to every
estimator's `add_fix`, which returns the monitor's verdict. A component that raises, or answers
with something else than a 4x4 pose or a Verdict, is recorded as failed from that input on and
the rest goes on. A scan the recording could not give (BadScan) is a recorded failure too. An
observer (the live view), when given, is told of each scan and fix as it is recorded.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import TextIO

import numpy as np

from fusion.monitors import Cn0Templates
from fusion.verdict import Verdict
from scenarios.pipeline.inertial import HeadingEvent, ImuEvent
from scenarios.pipeline.matcher_pool import MatcherPool
from scenarios.pipeline.observer import RunObserver
from scenarios.pipeline.stream import ScanEvent
from scenarios.score.record import Recorder, nan_pose
from scenarios.spec.scenario import Scenario

LOOKAHEAD_SCANS = 1
"""Scans read or simulated ahead of the one being matched (the overlap of reading or simulation and matching) where the
next input depends on the estimators' state: a closed loop steers on it, an export frame waits for it."""
PIPELINED_SCANS = 4
"""Scans ahead where the input does not depend on the estimators (a planned path, a recording): per-scan costs vary in
the run process and in the matchers' worker, unevenly, and a deeper queue lets one catch up while the other is slow
instead of waiting scan by scan (the same inputs in the same order: the outputs do not change)."""
PLANAR_AXES = [0, 1, 5]
"""Rows and columns of x, y and yaw in a 6x6 pose covariance [x, y, z, roll, pitch, yaw] (ROS geometry_msgs order)."""


@dataclass(frozen=True)
class BadScan:
    """A scan the recording holds but that could not be read (`source`: where it came from)."""

    stamp: float
    source: str
    reason: str


class RunFailed(RuntimeError):
    """The run could not go on (the simulation or the recording failed); nothing was written."""


class RunInterrupted(RuntimeError):
    """Ctrl-C: the run stopped cleanly; nothing was written."""


class Feed:
    """drive(events), or push(event) for each event in time order then finish(); `recorder` holds what came out."""

    def __init__(
        self,
        scenario: Scenario,
        pool: MatcherPool,
        recorder: Recorder,
        base_pose: Callable[[float], np.ndarray],
        t_start: float,
        log_fix: Callable[[object], None] | None = None,
        on_scan: Callable[[float, dict], None] | None = None,
        observer: RunObserver | None = None,
        lookahead_scans: int = LOOKAHEAD_SCANS,
    ) -> None:
        """log_fix(event), when given, is called with each fix event once the estimators have it (e.g. to write the NMEA log);
        on_scan(stamp, results) once every estimator has a scan and before any later input (e.g. to read their poses and
        covariances), with the matchers' results of that scan by id;
        observer, when given, with each scan and fix as they are recorded (the live view);
        lookahead_scans: scans submitted to the matchers before the oldest is fused (PIPELINED_SCANS when nothing fed
        back from the estimators shapes the input)."""
        self.pool, self.recorder, self.base_pose = pool, recorder, base_pose
        self.log_fix, self.on_scan, self.observer = log_fix, on_scan, observer
        self.sensors = {e.id: set(e.sensors_used) for e in scenario.estimators}
        self.feeds = {e.id: e.matcher if "odometry" in self.sensors[e.id] else None for e in scenario.estimators}
        self.refs = {c.id: c.ref for c in [*scenario.matchers, *scenario.estimators]}  # kind or plugin path: failures name it
        self.estimators, self.dead = build_estimators(scenario, recorder, t_start)
        self.queue: deque = deque()
        self.lookahead_scans = lookahead_scans
        self.scans = 0

    @property
    def maps_scans(self) -> bool:
        """Whether an estimator reads the scans' points (its monitor maps them, e.g. shadow)."""
        return any(getattr(est, "wants_scans", False) for est in self.estimators.values() if est is not None)

    def pose_of(self, estimator_id: str) -> np.ndarray:
        """An estimator's current pose (NaN when it failed or gives something else than a 4x4 pose)."""
        if estimator_id in self.dead:
            return nan_pose()
        try:
            return checked_pose(self.estimators[estimator_id].pose)
        except Exception:  # a plugin's pose may raise anything: steering sees an unknown pose, the scan step records the failure
            return nan_pose()

    def cov_of(self, estimator_id: str) -> np.ndarray | None:
        """An estimator's current covariance as 6x6 [x, y, z, roll, pitch, yaw]: its 3x3 (x, y, yaw) in those rows and
        columns, the rest zero (not estimated); None when it failed or gives no finite 3x3 or 6x6."""
        if estimator_id in self.dead:
            return None
        try:
            cov = np.asarray(self.estimators[estimator_id].cov, dtype=float)
        except Exception:  # a plugin's cov may raise anything or be anything: no covariance
            return None
        if cov.shape == (3, 3):
            cov, planar = np.zeros((6, 6)), cov
            cov[np.ix_(PLANAR_AXES, PLANAR_AXES)] = planar
        return cov if cov.shape == (6, 6) and np.isfinite(cov).all() else None

    def push(self, event) -> None:
        """Take the next event (ScanEvent, BadScan, or a fix event with `.fix`) and process what is due."""
        if isinstance(event, BadScan):
            self.recorder.failure("scan", event.source, event.stamp, event.reason)
            return
        self.queue.append(event)
        if isinstance(event, ScanEvent):
            self.pool.submit(event.scan)
            self.scans += 1
        self._drain(self.lookahead_scans)

    def finish(self) -> None:
        """Process every pending event."""
        self._drain(0)

    def drive(self, events, on_event: Callable[[object], None], failures: tuple[type[Exception], ...], where: str = "") -> None:
        """Push every event and finish; Ctrl-C becomes RunInterrupted and a `failures` exception RunFailed, both naming the scan and time."""
        now = math.nan
        try:
            for event in events:
                now = event.stamp
                self.push(event)
                on_event(event)
            self.finish()
        except KeyboardInterrupt:
            raise RunInterrupted(f"interrupted at t={now:.1f} s (scan {self.scans}); nothing written") from None
        except failures as exc:
            raise RunFailed(f"{where}scan {self.scans} at t={now:.2f} s: {exc}") from None

    def _drain(self, keep_scans: int) -> None:
        """Process queued events in order while more than `keep_scans` scans are queued, then the fixes at the front."""
        while self.queue and sum(isinstance(e, ScanEvent) for e in self.queue) > keep_scans:
            event = self.queue.popleft()
            if isinstance(event, ScanEvent):
                self._scan(event, *self.pool.collect())
            else:
                self._other(event)
        while self.queue and not isinstance(self.queue[0], ScanEvent):
            self._other(self.queue.popleft())

    def _other(self, event) -> None:
        """A fix, a batch of IMU samples or a compass heading to the estimators fed that sensor."""
        if isinstance(event, ImuEvent):
            self._each_estimator(lambda eid, est: est.add_imu(event.samples), event.stamp, "imu")
        elif isinstance(event, HeadingEvent):
            used = self._each_estimator(lambda eid, est: bool(est.add_heading(event.sample)), event.stamp, "compass")
            users = [eid for eid in self.estimators if "compass" in self.sensors[eid]]
            self.recorder.heading(event.stamp, event.sample.yaw, event.truth_yaw, {eid: used.get(eid, False) for eid in users})
        else:
            self._fix(event)

    def _each_estimator(self, call: Callable[[str, object], object], stamp: float, sensor: str | None = None) -> dict:
        """call(id, estimator) for every live estimator (fed `sensor`, when given); one that raises is failed from here on."""
        out = {}
        for eid, est in self.estimators.items():
            if eid in self.dead or (sensor is not None and sensor not in self.sensors[eid]):
                continue
            try:
                out[eid] = call(eid, est)
            except Exception as exc:  # an estimator that raises fails from this input on; the run goes on
                self.dead.add(eid)
                self.recorder.failure("estimator", eid, stamp, f"{self.refs[eid]}: {type(exc).__name__}: {exc}")
        return out

    def _scan(self, event: ScanEvent, results: dict, errors: dict) -> None:
        """The matchers' results of one scan to the estimators, then into the record."""
        for mid, why in errors.items():
            self.recorder.failure("matcher", mid, event.stamp, f"{self.refs[mid]}: {why}")

        points: list[np.ndarray] = []  # the scan's xyz (lidar frame), made once for the estimators that map it

        def step(eid: str, est) -> tuple[np.ndarray, float]:
            """Feed one estimator its matcher's result (none for gps_only), and the scan's points when its monitor maps
            them, and read its pose and protection level."""
            if self.feeds[eid]:
                est.add_match(event.stamp, results[self.feeds[eid]])
            if getattr(est, "wants_scans", False):
                if not points:
                    p = event.scan.points
                    points.append(np.column_stack([p["x"], p["y"], p["z"]]))
                est.add_scan(event.stamp, points[0])
            return checked_pose(est.pose), checked_level(getattr(est, "protection_level", math.nan))

        stepped = self._each_estimator(step, event.stamp)
        truth = self.base_pose(event.stamp)
        estimates = {eid: stepped[eid][0] if eid in stepped else nan_pose() for eid in self.estimators}
        levels = {eid: stepped[eid][1] if eid in stepped else math.nan for eid in self.estimators}
        self.recorder.scan(event.stamp, truth, results, estimates, levels)
        if self.observer is not None:
            self.observer.scan(event, truth, estimates)
        if self.on_scan is not None:
            self.on_scan(event.stamp, results)

    def _fix(self, event) -> None:
        """One fix to every estimator, its verdicts into the record, then to log_fix and the observer."""
        fix = event.fix
        verdicts = self._each_estimator(lambda eid, est: checked_verdict(est.add_fix(fix)), fix.stamp, "gnss")
        # a failed estimator (or one not fed GPS) raises no alarm: its fixes count as trusted with no statistic
        self.recorder.fix(
            fix,
            {
                eid: (verdicts[eid].trusted, verdicts[eid].statistic, refusing_rule(verdicts[eid])) if eid in verdicts else (True, math.nan, "")
                for eid in self.estimators
            },
        )
        if self.log_fix is not None:
            self.log_fix(event)
        if self.observer is not None:
            self.observer.fix(fix, verdicts)


def build_estimators(scenario: Scenario, recorder: Recorder, t_start: float) -> tuple[dict, set[str]]:
    """Every estimator by id, and the ids of those whose constructor raised (recorded as failed from the start). Their
    cn0 monitors share the receiver's C/N0 templates, learning each fix once."""
    estimators, dead = {}, set()
    templates = Cn0Templates()
    for spec in scenario.estimators:
        try:
            estimators[spec.id] = spec.build(scenario.seed, templates)
        except Exception as exc:  # a plugin's constructor may raise anything: that estimator fails, the run goes on
            estimators[spec.id] = None
            dead.add(spec.id)
            recorder.failure("estimator", spec.id, t_start, f"{spec.ref}: could not be built: {type(exc).__name__}: {exc}")
    return estimators, dead


def checked_pose(pose) -> np.ndarray:
    """An estimator's pose as a 4x4 float array, or a TypeError (a plugin's may be anything)."""
    matrix = np.asarray(pose, dtype=float)
    if matrix.shape != (4, 4):
        raise TypeError(f"pose has shape {matrix.shape}, not (4, 4)")
    return matrix


def checked_level(level) -> float:
    """An estimator's horizontal protection level in metres (NaN when it reports none), or a TypeError."""
    try:
        return float(level)
    except (TypeError, ValueError):
        raise TypeError(f"protection_level is a {type(level).__name__}, not a number") from None


def refusing_rule(verdict: Verdict) -> str:
    """The rule a fix is recorded under: a refused one's, or "unnamed" when a plugin's monitor gave none; a fix trusted
    with an allowance, the rule that gave it; "" when trusted outright."""
    if verdict.trusted:
        return verdict.rule if verdict.allowance_m > 0 else ""
    return verdict.rule or "unnamed"


def checked_verdict(verdict) -> Verdict:
    """What add_fix returned, if it is a fusion Verdict, or a TypeError (a plugin's may be anything)."""
    if not isinstance(verdict, Verdict):
        raise TypeError(f"add_fix returned a {type(verdict).__name__}, not a fusion.Verdict")
    return verdict


def nmea_writer(log: TextIO, sentences: Callable[[object], list[str]]) -> Callable[[object], None]:
    """A Feed's log_fix that appends each fix event's NMEA sentences (CR LF terminated, as a receiver sends them) to `log`."""

    def write(event) -> None:
        lines = sentences(event)
        if lines:
            log.write("\r\n".join(lines) + "\r\n")

    return write
