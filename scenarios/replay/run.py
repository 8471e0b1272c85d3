"""`replay(recording, scenario, out_dir)`: a scenario's matchers and estimators over a real recording, no truth.

The recording (a rosbag2 or ROS 1 bag, a Velodyne pcap, or an NMEA log; `nmea`: an NMEA
log whose fixes replace a capture's or bag's own GPS) gives the scans and fixes in time order;
scenarios.pipeline.feed runs them through the scenario's matchers and estimators with the calls
of a simulated run. A recording without LiDAR (an NMEA log alone, a bag of NMEA sentences or
NavSatFix only) is a GNSS-only replay: the estimators run without a matcher (no odometry) and
their poses are sampled right after each fix (a scan of no points that no matcher sees); each of the
scenario's matchers gets a TUM file of its header only (it never produced a pose: a run and a replay write the same
files for the same components) and metrics.json says `run.gnss_only`. Everything the scenario says about the world and the sensors' simulation is
unused, except the world's geodetic origin (the ENU frame), the GNSS epoch (the time base) and the
boat's configuration (lidar mount, antenna offset). Matcher odometry is chained from identity at
the first scan, then moved as a whole onto the first estimate that has a heading (at that scan or
the matcher's first after it; scenarios.replay.anchor), recorded in metrics.json as run.anchor;
without any estimate it stays chained from identity at the world origin. The run directory is written under a hidden name and renamed when complete:

    scenario.toml  metrics.json (scenarios.replay.metrics)  <id>.tum per estimator and matcher (UNIX time: the
                   recording's own clock; at the waterline, as scenarios.pipeline.files writes a run's)
    gps.csv (every fix with each verdict)  gps.nmea (the recorded sentences, when there are any)
    report.md  report.html  plots/map.png
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np
import tomli_w

import scenarios
import worlds
from riverbench import provenance
from riverbench.provenance import peak_rss_mb
from scenarios.export import check_out, staged_dir
from scenarios.pipeline import files
from scenarios.pipeline.assembly import matcher_setups
from scenarios.pipeline.assembly import recorder as make_recorder
from scenarios.pipeline.feed import PIPELINED_SCANS, Feed, nmea_writer
from scenarios.pipeline.matcher_pool import MatcherPool
from scenarios.pipeline.stream import ScanEvent
from scenarios.replay import anchor, bag, capture, gates, nmea_log, pcap
from scenarios.replay import metrics as replay_metrics
from scenarios.replay import reference as reference_module
from scenarios.replay.recording import Event, Place, RecordedFix, Recording
from scenarios.replay.reference import Reference
from scenarios.score import metrics as run_metrics
from scenarios.score import units
from scenarios.spec.scenario import Scenario
from sim.scan import Scan

if TYPE_CHECKING:
    from fusion.verdict import Verdict
    from sim.gnss_fix import GnssFix


@dataclass
class ReplayResult:
    """A finished replay: the scenario and recording it used, where its run directory is, and its metrics tree."""

    scenario: Scenario
    recording: Recording
    out_dir: Path
    metrics: dict

    @property
    def report(self) -> Path:
        """The HTML report's path (written when the replay was asked for a report)."""
        return self.out_dir / "report.html"


@dataclass(frozen=True)
class Replaying:
    """What a replay's observer is begun with in place of a run's assembled stack (there is no world and no truth): the
    scenario whose estimators run, the opened recording, and the reference (None without --reference)."""

    scenario: Scenario
    recording: Recording
    reference: Reference | None


class ReplayObserver(Protocol):
    """A watcher of a replay (the live view, scenarios.view.replay_view): scenarios.pipeline.observer.RunObserver's scan, fix
    and close, begun with a Replaying. The Feed's `truth` is the identity (a replay has none): a replay observer ignores it."""

    def begin(self, replaying: Replaying, run_dir: Path) -> None: ...

    def scan(self, event: ScanEvent, truth: np.ndarray, estimates: dict[str, np.ndarray]) -> None: ...

    def fix(self, fix: GnssFix, verdicts: dict[str, Verdict]) -> None: ...

    def close(self, keep: bool) -> None: ...


def default_out_dir(recording: str | os.PathLike) -> Path:
    """runs/replay-<recording's name>-<UTC time>/."""
    return Path("runs") / f"replay-{Path(recording).stem}-{datetime.now(UTC):%Y%m%dT%H%M%SZ}"


def replay(
    recording: str | os.PathLike,
    scenario: Scenario | str | os.PathLike,
    out_dir: str | os.PathLike | None = None,
    *,
    lidar_topic: str | None = None,
    gps_topic: str | None = None,
    imu_topic: str | None = None,
    nmea: str | os.PathLike | None = None,
    reference: str | os.PathLike | None = None,
    workers: int = 1,
    report: bool = True,
    progress: Callable[[float, float, float, int], None] | None = None,
    observer: ReplayObserver | None = None,
) -> ReplayResult:
    """Replay `recording` through `scenario`'s matchers and estimators into a run directory (default runs/replay-<name>-<UTC time>/).

    A recording that cannot be read, a topic that is not in it or that is ambiguous, a capture
    without data packets, an NMEA log without a usable epoch, a log or reference (scenarios.replay.reference)
    that does not overlap the recording: ValueError, one line, nothing written. workers: processes for the matchers (1: all in this one).
    progress, if given, is called as progress(t, t_start, t_end, scans). observer, if given, is begun with the replay once its
    inputs are read, sees each scan and fix, and is closed (keep=True) before the run directory is renamed into place, or
    (keep=False) when the replay fails.
    """
    scenario = scenario if isinstance(scenario, Scenario) else scenarios.load(scenario)
    path = Path(recording)
    out = Path(out_dir) if out_dir is not None else default_out_dir(path)
    check_out(out, directory=True)
    world = worlds.load(scenario.world, **scenario.world_params)
    place = Place(tuple(world.origin), scenario.gnss.epoch_utc, scenario.lidar.start_azimuth_deg, imu_noise(scenario), compass_sigma(scenario))
    read_start = time.perf_counter()
    opened = open_recording(path, place, lidar_topic, gps_topic, imu_topic)
    read_s = time.perf_counter() - read_start
    if nmea is not None:
        if opened.gnss_only:
            raise ValueError(f"{path}: --nmea gives the GPS of a recording with LiDAR; this one has none (replay the NMEA log alone)")
        opened = nmea_log.attach(opened, nmea, place)
    ref = None
    if reference is not None:
        ref = reference_module.read(reference, opened.geo, place)
        ref.overlap(opened)
    with staged_dir(out) as tmp:
        try:
            if observer is not None:
                observer.begin(Replaying(scenario, opened, ref), tmp)
            tree = replay_into(scenario, opened, tmp, workers, progress, ref, read_s, observer)
            if report:
                from scenarios.replay import report as report_module

                report_module.write(tmp)
            if observer is not None:
                observer.close(keep=True)  # before the rename: what it writes into the run directory is complete
        finally:
            if observer is not None:
                observer.close(keep=False)  # a no-op after close(keep=True)
    return ReplayResult(scenario, opened, out, tree)


def imu_noise(scenario: Scenario) -> tuple[float, float] | None:
    """The scenario's IMU white-noise densities in SI (gyro, accel) when an estimator is fed the IMU, else None."""
    if scenario.imu is None or not any("imu" in e.sensors_used for e in scenario.estimators):
        return None
    gyro, accel = scenario.imu.noise_specs()
    return gyro.white, accel.white


def compass_sigma(scenario: Scenario) -> float | None:
    """The scenario's compass heading accuracy (rad) when an estimator is fed the compass, else None."""
    if scenario.compass is None or not any("compass" in e.sensors_used for e in scenario.estimators):
        return None
    return math.radians(scenario.compass.heading_sigma_deg)


def open_recording(path: Path, place: Place, lidar_topic: str | None, gps_topic: str | None, imu_topic: str | None = None) -> Recording:
    """The recording at `path`: a capture by its name or its libpcap magic number, an NMEA log (scenarios.replay.nmea_log.is_log),
    else a bag."""
    if path.suffix.lower() in (".pcap", ".pcapng") or (path.is_file() and capture.is_capture(path)):
        if lidar_topic or gps_topic or imu_topic:
            raise ValueError(f"{path}: a pcap has no topics (--lidar-topic, --gps-topic and --imu-topic are for bags)")
        return pcap.read(path, place)
    if nmea_log.is_log(path):
        if lidar_topic or gps_topic or imu_topic:
            raise ValueError(f"{path}: an NMEA log has no topics (--lidar-topic, --gps-topic and --imu-topic are for bags)")
        return nmea_log.read(path, place)
    return bag.read(path, place, lidar_topic, gps_topic, imu_topic)


def without_matchers(scenario: Scenario) -> Scenario:
    """The scenario's estimators with no matcher (a GNSS-only replay): what they do on fixes alone."""
    return scenario.model_copy(update={"matchers": [], "estimators": [e.model_copy(update={"matcher": None}) for e in scenario.estimators]})


def pose_samples(events: Iterator[Event]) -> Iterator[Event]:
    """The events with, right after each fix, a scan of no points at its stamp: where a GNSS-only replay reads the estimators' poses."""
    for event in events:
        yield event
        if isinstance(event, RecordedFix):
            yield ScanEvent(event.stamp, Scan.empty(event.stamp))


def replay_into(
    scenario: Scenario,
    recording: Recording,
    tmp: Path,
    workers: int,
    progress,
    ref: Reference | None = None,
    read_s: float = 0.0,
    observer: ReplayObserver | None = None,
) -> dict:
    """Stream the recording through the matchers and estimators and write the run directory's data files into `tmp`
    (scored against the reference `ref` when there is one). wall_s (and the realtime factor) is the streaming's, from the
    matcher processes being ready to the files written; opening the recording (read_s: a pcap's first pass) and starting
    the processes (startup_s) are stated apart."""
    startup = time.perf_counter()
    fed = without_matchers(scenario) if recording.gnss_only else scenario
    recorder = make_recorder(fed)
    setups = matcher_setups(fed)
    start = np.eye(4)
    events = pose_samples(recording.events()) if recording.gnss_only else recording.events()
    headings, refusals = anchor.HeadingLog([e.id for e in fed.estimators]), gates.RefusalTally(fed)

    def on_scan(stamp: float, results: dict) -> None:
        headings(stamp)
        refusals(stamp, results)

    with MatcherPool(setups, workers) as pool, open(tmp / "gps.nmea", "w", newline="") as nmea:
        wall_start = time.perf_counter()
        log = nmea_writer(nmea, lambda event: list(event.sentences))
        feed = Feed(
            fed, pool, recorder, lambda stamp: start, recording.t_start, log, on_scan=on_scan, observer=observer, lookahead_scans=PIPELINED_SCANS
        )
        headings.sd_of = lambda eid: anchor.yaw_sd_deg(feed.cov_of(eid))
        feed.drive(
            events,
            lambda event: (
                progress is not None and isinstance(event, ScanEvent) and progress(event.stamp, recording.t_start, recording.t_end, feed.scans)
            ),
            (ValueError, RuntimeError, OSError),
            where=f"{recording.path}: ",
        )
        pool.close()
        workers_rss, lanes = pool.workers_rss_mb, pool.lanes
    startups = {eid: replay_metrics.startup(estimator, recording.t_start) for eid, estimator in feed.estimators.items()}
    if not (tmp / "gps.nmea").stat().st_size:
        (tmp / "gps.nmea").unlink()
    rec = recorder.finish([])
    start_pose = anchor.choose(rec, headings)
    rec = anchor.anchored(rec, start_pose)
    wall = time.perf_counter() - wall_start
    geo = recording.geo
    run_info = {
        "scenario": scenario.name,
        "scenario_hash": scenario.hash,
        "recording": {
            "path": str(recording.path),
            "format": recording.format,
            "lidar": recording.lidar_source,
            "gps": recording.gps_source,
            **({"imu": recording.imu_source} if recording.imu_source else {}),
            **({"compass": recording.compass_source} if recording.compass_source else {}),
            "time_zero_utc": geo.utc(0.0).isoformat(),
            "origin": list(geo.origin),
            "origin_from": geo.origin_source,
            **({"nmea": {**recording.nmea.tree(), "summary": recording.nmea.summary()}} if recording.nmea is not None else {}),
            **recording.facts,
        },
        "gnss_only": recording.gnss_only,
        "t_start": recording.t_start,
        "t_end": recording.t_end,
        "duration_s": recording.t_end - recording.t_start,
        "wall_s": wall,
        "realtime_factor": (recording.t_end - recording.t_start) / wall if wall > 0 else math.nan,
        "read_s": read_s,
        "startup_s": wall_start - startup,
        "peak_rss_mb": peak_rss_mb() + workers_rss,
        "scans": 0 if recording.gnss_only else len(rec.scan_t),
        **({"pose_samples": len(rec.scan_t)} if recording.gnss_only else {}),
        "fixes": len(rec.fixes.t),
        "workers": len(lanes),
        "lanes": lanes,
        "failures": rec.failures,
        "warnings": refusals.warnings(),
        "anchor": start_pose.describe(float(rec.scan_t[start_pose.index])) if start_pose is not None else None,
    }
    antenna = np.asarray(scenario.gnss.antenna_offset_m, dtype=float)
    tree = replay_metrics.compute(rec, run_info, antenna, startups)
    if ref is not None:
        tree["reference"] = ref.tree()
        for eid, node in tree["estimators"].items():
            node["against_reference"] = reference_module.score(rec, eid, ref, antenna)
    tree = units.rounded(run_metrics.json_safe(tree))
    (tmp / "scenario.toml").write_text(
        f"# resolved scenario {scenario.hash}: its matchers and estimators replayed over {recording.path}"
        + (" (GNSS-only: the estimators without their matchers)" if recording.gnss_only else "")
        + "\n"
        + tomli_w.dumps(scenario.resolved())
    )
    tree = {"provenance": provenance.collect(), **tree, "units": units.block()}
    (tmp / "metrics.json").write_text(json.dumps(tree, indent=2) + "\n")
    for eid, poses in rec.estimates.items():
        files.write_tum(tmp / f"{eid}.tum", rec.scan_t, files.waterline(poses), geo.zero_ns)
    for mid, track in rec.matches.items():
        files.write_tum(tmp / f"{mid}.tum", rec.scan_t, files.waterline(track.pose), geo.zero_ns)
    for matcher in scenario.matchers:
        if matcher.id not in rec.matches:  # not run (a GNSS-only replay): no pose, its file as a run writes one
            files.write_tum(tmp / f"{matcher.id}.tum", np.zeros(0), np.zeros((0, 4, 4)), geo.zero_ns)
    files.write_gps_csv(tmp / "gps.csv", rec, truth=False)
    return tree
