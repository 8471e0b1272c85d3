"""Record one simulated stream (match results of one matcher, fixes, truth) so estimators can be replayed.

Simulating the LiDAR and matching dominate a route's wall time; the monitors and estimators under
test only need each scan's MatchResult, each GnssFix and the truth pose per scan. A recording is
pickled under benchmarks/out keyed by world, matcher, seed, span, the `--set` settings and a digest
of the simulating code (worlds/, sim/, matcher/, scenarios/stream.py), and reused when present.

`--set section.key=value` (repeatable; values typed as TOML, as `riverbench run --set`) passes
extra keyword arguments to what the stream is built from: `world` (the preset's parameters),
`vessel` (sim.Trajectory), `lidar` (sim.HDL32E), `gnss` (sim.GnssReceiver), `matcher` (its params),
`traffic` (sim.TrafficConfig: moving boats, e.g. `traffic.movers=[{kind="chase"}]`), so that a
recording can be made again in a changed world.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import matcher
import sim
import worlds
from scenarios.pipeline.stream import FixEvent, events, pose_xyzyaw
from scenarios.spec.overrides import parse_value
from sim.gnss import GnssReceiver

SECTIONS = ("world", "vessel", "lidar", "gnss", "matcher", "traffic")


@dataclass
class Recording:
    """Time-ordered ('scan', stamp, MatchResult, truth xyzyaw) and ('fix', stamp, GnssFix) items, and the run's provenance."""

    world: str
    matcher: str
    seed: int
    t_start: float
    t_end: float
    items: list
    wall_s: float
    settings: dict | None = None


def parse_settings(assignments: list[str]) -> dict[str, dict]:
    """{section: {key: value}} from 'section.key=value' strings (ValueError naming a bad one)."""
    settings: dict[str, dict] = {}
    for assignment in assignments:
        key, sep, raw = assignment.partition("=")
        section, dot, name = key.strip().partition(".")
        if not sep or not dot or not name or section not in SECTIONS:
            raise ValueError(f"--set {assignment!r}: write section.key=value with section one of {', '.join(SECTIONS)}")
        settings.setdefault(section, {})[name] = parse_value(raw.strip())
    return settings


@dataclass
class Stream:
    """What one recording simulates: the scene the sensors see (the world, with traffic if any), the
    vessel's trajectory, the LiDAR, the receiver and the matcher's parameters."""

    scene: object
    trajectory: sim.Trajectory
    lidar: sim.HDL32E
    receiver: GnssReceiver
    matcher_params: dict


def build(world_name: str, seed: int, settings: dict | None = None) -> Stream:
    """The stream's parts for a world and seed, with the `--set` settings applied."""
    opts = {section: dict((settings or {}).get(section, {})) for section in SECTIONS}
    world = worlds.load(world_name, **opts["world"])
    trajectory = sim.Trajectory(world, seed=seed, **opts["vessel"])
    scene = sim.Scene(world, sim.build_traffic(sim.TrafficConfig(**opts["traffic"]), world, trajectory)) if opts["traffic"] else world
    return Stream(scene, trajectory, sim.HDL32E(seed=seed, **opts["lidar"]), GnssReceiver(seed=seed, **opts["gnss"]), opts["matcher"])


def record(
    world_name: str, matcher_name: str, seed: int, t_start: float, t_end: float | None, every_s: float = 120.0, settings: dict | None = None
) -> Recording:
    """Simulate the real stack (world, Trajectory, HDL32E, GnssReceiver, matcher) once and keep what the filters see."""
    stream = build(world_name, seed, settings)
    trajectory = stream.trajectory
    t_end = trajectory.duration if t_end is None else min(t_end, trajectory.duration)
    m = matcher.create(matcher_name, **stream.matcher_params)
    items, start, next_report = [], time.perf_counter(), t_start + every_s
    for event in events(stream.scene, trajectory, stream.lidar, stream.receiver, t_start, t_end):
        if isinstance(event, FixEvent):
            items.append(("fix", event.stamp, event.fix))
        else:
            items.append(("scan", event.stamp, m.register(event.scan), pose_xyzyaw(trajectory.pose(event.stamp))))
        if event.stamp >= next_report:
            rate = (event.stamp - t_start) / (time.perf_counter() - start)
            print(f"  ... {event.stamp:7.1f} / {t_end:.0f} s simulated ({rate:.2f}x real time)", flush=True)
            next_report += every_s
    return Recording(world_name, matcher_name, seed, t_start, float(t_end), items, time.perf_counter() - start, settings or None)


def code_digest() -> str:
    """Short digest of every source file that shapes a recording, so a code change records afresh."""
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for path in sorted([*root.glob("worlds/*.py"), *root.glob("sim/*.py"), *root.glob("matcher/*.py"), root / "scenarios" / "stream.py"]):
        h.update(path.name.encode())
        h.update(path.read_bytes())
    return h.hexdigest()[:10]


def add_recording_args(parser) -> None:
    """The command-line options that pick a recording: --world, --matcher, --seed, --out, --set."""
    parser.add_argument("--world", default="charles_river")
    parser.add_argument("--matcher", default="gicp")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", default="benchmarks/out")
    parser.add_argument(
        "--set",
        dest="settings",
        action="append",
        default=[],
        metavar="SECTION.KEY=VALUE",
        help=f"extra keyword argument for the stream, section one of {', '.join(SECTIONS)} "
        "(e.g. world.buildings=false, lidar.range_noise_m=0.03); repeatable",
    )


def settings_tag(settings: dict | None) -> str:
    """'' without settings, else '_set' and a short digest of them (part of a recording's file name)."""
    if not settings:
        return ""
    return "_set" + hashlib.sha256(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:8]


def load_or_record(
    out: Path, world_name: str, matcher_name: str, seed: int, t_start: float, t_end: float | None, settings: dict | None = None
) -> Recording:
    """The cached recording for these settings, or a fresh one written atomically (temp name, then rename)."""
    span = f"{t_start:g}-{'end' if t_end is None else f'{t_end:g}'}"
    path = out / f"stream_{world_name}_{matcher_name}_s{seed}_{span}{settings_tag(settings)}_{code_digest()}.pkl"
    if path.exists():
        with path.open("rb") as f:
            rec = pickle.load(f)
        print(f"replaying {path} (recorded in {rec.wall_s:.0f} s wall)")
        return rec
    rec = record(world_name, matcher_name, seed, t_start, t_end, settings=settings)
    out.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(".tmp")
    with tmp.open("wb") as f:
        pickle.dump(rec, f, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(tmp, path)
    print(f"recorded {path} in {rec.wall_s:.0f} s wall")
    return rec


def replay(rec: Recording, estimators: dict) -> dict:
    """Feed every estimator the recording in time order; per scan its pose, per fix its verdict.

    Returns arrays: scan_stamp (N,), truth (N, 4), estimate[name] (N, 4), fix_stamp (M,),
    fix (list of GnssFix), trusted[name] (M,), statistic[name] (M,).
    """
    scan_stamp, truth, fixes = [], [], []
    estimate = {n: [] for n in estimators}
    trusted = {n: [] for n in estimators}
    statistic = {n: [] for n in estimators}
    for item in rec.items:
        if item[0] == "scan":
            _, stamp, result, pose = item
            for n, est in estimators.items():
                if getattr(est, "uses_odometry", True):
                    est.add_match(stamp, result)
                estimate[n].append(pose_xyzyaw(est.pose))
            scan_stamp.append(stamp)
            truth.append(pose)
        else:
            _, stamp, fix = item
            for n, est in estimators.items():
                v = est.add_fix(fix)
                trusted[n].append(bool(v.trusted))
                statistic[n].append(float(v.statistic))
            fixes.append(fix)
    return {
        "scan_stamp": np.asarray(scan_stamp),
        "truth": np.asarray(truth).reshape(-1, 4),
        "estimate": {n: np.asarray(v).reshape(-1, 4) for n, v in estimate.items()},
        "fix_stamp": np.asarray([f.stamp for f in fixes]),
        "fix": fixes,
        "trusted": {n: np.asarray(v, dtype=bool) for n, v in trusted.items()},
        "statistic": {n: np.asarray(v, dtype=float) for n, v in statistic.items()},
    }
