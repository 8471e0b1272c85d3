"""`replay(recording, scenario, out_dir)`: a scenario's matchers and estimators over a real recording, no truth.

The recording (a rosbag2 or ROS 1 bag, or a Velodyne pcap) gives the scans and fixes in
time order; scenarios.pipeline.feed runs them through the scenario's matchers and estimators with the calls
of a simulated run. Everything the scenario says about the world and the sensors' simulation is
unused, except the world's geodetic origin (the ENU frame), the GNSS epoch (the time base) and the
boat's configuration (lidar mount, antenna offset). Matcher odometry is chained from identity at
the first scan, then moved as a whole onto the first estimate that has a heading (at that scan or
the matcher's first after it; scenarios.replay.anchor), recorded in metrics.json as run.anchor;
without any estimate it stays chained from identity at the world origin. The run directory is written under a hidden name and renamed when complete:

    scenario.toml  metrics.json (scenarios.replay.metrics)  <id>.tum per estimator and matcher
    gps.csv (every fix with each verdict)  gps.nmea (the recorded sentences, when there are any)
    report.md  report.html  plots/map.png
"""

from __future__ import annotations

import json
import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

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
from scenarios.pipeline.feed import Feed, nmea_writer
from scenarios.pipeline.matcher_pool import MatcherPool
from scenarios.pipeline.stream import ScanEvent
from scenarios.replay import anchor, bag, capture, gates, pcap
from scenarios.replay import metrics as replay_metrics
from scenarios.replay.recording import Place, Recording
from scenarios.score import metrics as run_metrics
from scenarios.spec.scenario import Scenario


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


def replay(
    recording: str | os.PathLike,
    scenario: Scenario | str | os.PathLike,
    out_dir: str | os.PathLike | None = None,
    *,
    lidar_topic: str | None = None,
    gps_topic: str | None = None,
    workers: int = 1,
    report: bool = True,
    progress: Callable[[float, float, float, int], None] | None = None,
) -> ReplayResult:
    """Replay `recording` through `scenario`'s matchers and estimators into a run directory (default runs/replay-<name>-<UTC time>/).

    A recording that cannot be read, a topic that is not in it or that is ambiguous, a capture
    without data packets: ValueError, one line, nothing written. workers: processes for the
    matchers (1: all in this one). progress, if given, is called as progress(t, t_start, t_end, scans).
    """
    scenario = scenario if isinstance(scenario, Scenario) else scenarios.load(scenario)
    path = Path(recording)
    out = Path(out_dir) if out_dir is not None else Path("runs") / f"replay-{path.stem}-{datetime.now(UTC):%Y%m%dT%H%M%SZ}"
    check_out(out, directory=True)
    world = worlds.load(scenario.world, **scenario.world_params)
    place = Place(tuple(world.origin), scenario.gnss.epoch_utc, scenario.lidar.start_azimuth_deg)
    read_start = time.perf_counter()
    opened = open_recording(path, place, lidar_topic, gps_topic)
    read_s = time.perf_counter() - read_start
    with staged_dir(out) as tmp:
        tree = replay_into(scenario, opened, tmp, workers, progress, read_s)
        if report:
            from scenarios.replay import report as report_module

            report_module.write(tmp)
    return ReplayResult(scenario, opened, out, tree)


def open_recording(path: Path, place: Place, lidar_topic: str | None, gps_topic: str | None) -> Recording:
    """The recording at `path`: a capture by its name or its libpcap magic number, else a bag."""
    if path.suffix.lower() in (".pcap", ".pcapng") or (path.is_file() and capture.is_capture(path)):
        if lidar_topic or gps_topic:
            raise ValueError(f"{path}: a pcap has no topics (--lidar-topic and --gps-topic are for bags)")
        return pcap.read(path, place)
    return bag.read(path, place, lidar_topic, gps_topic)


def replay_into(scenario: Scenario, recording: Recording, tmp: Path, workers: int, progress, read_s: float = 0.0) -> dict:
    """Stream the recording through the matchers and estimators and write the run directory's data files into `tmp`.
    wall_s (and the realtime factor) is the streaming's, from the matcher processes being ready to the last event;
    opening the recording (read_s: a pcap's first pass) and starting the processes (startup_s) are stated apart."""
    startup = time.perf_counter()
    recorder = make_recorder(scenario)
    setups = matcher_setups(scenario)
    start = np.eye(4)
    headings, refusals = anchor.HeadingLog([e.id for e in scenario.estimators]), gates.RefusalTally(scenario)

    def after_scan(stamp: float, results: dict) -> None:
        headings(stamp)
        refusals(stamp, results)

    with MatcherPool(setups, workers) as pool, open(tmp / "gps.nmea", "w", newline="") as nmea:
        wall_start = time.perf_counter()
        log = nmea_writer(nmea, lambda event: list(event.sentences))
        feed = Feed(scenario, pool, recorder, lambda stamp: start, recording.t_start, log, after_scan=after_scan)
        headings.sd_of = feed.yaw_sd_deg
        feed.drive(
            recording.events(),
            lambda event: (
                progress is not None and isinstance(event, ScanEvent) and progress(event.stamp, recording.t_start, recording.t_end, feed.scans)
            ),
            (ValueError, RuntimeError, OSError),
            where=f"{recording.path}: ",
        )
        pool.close()
        workers_rss, lanes = pool.workers_rss_mb, pool.lanes
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
            "time_zero_utc": geo.utc(0.0).isoformat(),
            "origin": list(geo.origin),
            "origin_from": geo.origin_source,
            **recording.facts,
        },
        "t_start": recording.t_start,
        "t_end": recording.t_end,
        "duration_s": recording.t_end - recording.t_start,
        "wall_s": wall,
        "realtime_factor": (recording.t_end - recording.t_start) / wall if wall > 0 else math.nan,
        "read_s": read_s,
        "startup_s": wall_start - startup,
        "peak_rss_mb": peak_rss_mb() + workers_rss,
        "scans": len(rec.scan_t),
        "fixes": len(rec.fixes.t),
        "workers": len(lanes),
        "lanes": lanes,
        "failures": rec.failures,
        "warnings": refusals.warnings(),
        "anchor": start_pose.describe(float(rec.scan_t[start_pose.index])) if start_pose is not None else None,
    }
    tree = run_metrics.json_safe(replay_metrics.compute(rec, run_info, np.asarray(scenario.gnss.antenna_offset_m, dtype=float)))
    (tmp / "scenario.toml").write_text(
        f"# resolved scenario {scenario.hash}: its matchers and estimators replayed over {recording.path}\n" + tomli_w.dumps(scenario.resolved())
    )
    tree = {"provenance": provenance.collect(), **tree}
    (tmp / "metrics.json").write_text(json.dumps(tree, indent=2) + "\n")
    for eid, poses in rec.estimates.items():
        files.write_tum(tmp / f"{eid}.tum", rec.scan_t, poses)
    for mid, track in rec.matches.items():
        files.write_tum(tmp / f"{mid}.tum", rec.scan_t, track.pose)
    files.write_gps_csv(tmp / "gps.csv", rec, truth=False)
    return tree
