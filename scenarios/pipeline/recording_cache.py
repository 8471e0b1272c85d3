"""The recordings command components read, written once per setup and reused: a sweep over a command's parameters, or
runs at one seed, export the same sensor stream once.

A recording is the scenario's sensor stream (scans, fixes, the truth, the mounts; no matcher's or estimator's output)
in one format. Its key is a digest of the resolved scenario without what cannot change the stream (name, description,
expectations, goals, [fast], the command components; in open loop also the matchers and estimators, which then only
watch it), of the format and of the source of the packages that simulate and write it, so an edited simulator never
reuses a stale recording. It lives at <cache>/recordings/<key>/ (cache: $RIVERBENCH_CACHE, else
$XDG_CACHE_HOME/riverbench, else ~/.cache/riverbench), written under a hidden name and renamed into place whole: a
reader sees a complete recording or none. The writer holds a lock on <key>.lock beside it (fcntl.flock, released by
the kernel when its process ends, however it ends): two runs after one key, such as two sweep workers at one seed,
write it once, the second waiting for the first and reading what it wrote.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import secrets
import shutil
import time
from dataclasses import dataclass
from pathlib import Path

from scenarios.spec.scenario import Scenario

SOURCES = ("riverbench", "worlds", "sim", "scenarios/export", "scenarios/pipeline")
"""The code a recording depends on, relative to the source root: its digest is part of every key."""
AFTER_THE_STREAM = ("command.py", "external.py", "rescore.py", "runner.py")
"""Modules of scenarios/pipeline that only run and score the commands: editing them keeps the recordings."""
ROOT = Path(__file__).resolve().parents[2]
NAMES = {"rosbag2": "recording", "mcap": "recording", "kitti": "recording", "pcap": "recording.pcap", "nmea": "recording.nmea"}
"""The recording's name inside its cache folder, by format (a bag or KITTI directory, or a file)."""
NAME = "recording"
"""The scenario name the recording is written under (a bag's file names carry it): the same for every scenario."""


@dataclass(frozen=True)
class Recording:
    """A recording ready to read: its path, whether the cache had it, and the seconds spent getting it (writing it, or
    finding it)."""

    path: Path
    hit: bool
    seconds: float


def cache_root() -> Path:
    """Where riverbench keeps what it can make again: $RIVERBENCH_CACHE, else $XDG_CACHE_HOME/riverbench, else ~/.cache/riverbench."""
    if os.environ.get("RIVERBENCH_CACHE"):
        return Path(os.environ["RIVERBENCH_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "riverbench"


def stream_scenario(scenario: Scenario) -> Scenario:
    """The scenario whose sensor stream the recording holds: without command components, expectations and goals, and
    (open loop) without matchers and estimators."""
    data = {k: v for k, v in scenario.resolved().items() if k not in ("fast", "expect", "goals", "description")}
    data["name"] = NAME
    data["matchers"] = [m for m in data["matchers"] if m.get("kind") != "command"]
    data["estimators"] = [e for e in data["estimators"] if e.get("kind") != "command"]
    if scenario.control.mode == "open_loop":
        data["matchers"], data["estimators"] = [], []
    return Scenario.model_validate(data)


def key(scenario: Scenario, fmt: str) -> str:
    """The cache key of `scenario`'s recording in format `fmt`."""
    setup = {k: v for k, v in stream_scenario(scenario).resolved().items() if k != "name"}
    text = json.dumps({"setup": setup, "format": fmt, "code": code_digest()}, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def code_digest() -> str:
    """A digest of the Python source that simulates and writes a recording."""
    digest = hashlib.sha256()
    for folder in SOURCES:
        for path in sorted((ROOT / folder).rglob("*.py")):
            if folder == "scenarios/pipeline" and path.name in AFTER_THE_STREAM:
                continue
            digest.update(str(path.relative_to(ROOT)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def get(scenario: Scenario, fmt: str, root: Path | None = None) -> Recording:
    """The recording of `scenario` in `fmt` from the cache, written there first when it is not (under the key's lock,
    so it is written once however many runs ask for it at the same time)."""
    start = time.perf_counter()
    folder = (root or cache_root()) / "recordings" / key(scenario, fmt)
    if folder.is_dir():
        return Recording(folder / NAMES[fmt], True, time.perf_counter() - start)
    folder.parent.mkdir(parents=True, exist_ok=True)
    with open(folder.parent / f"{folder.name}.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # waits while another process writes this key
        if folder.is_dir():  # it did: theirs is the same recording
            return Recording(folder / NAMES[fmt], True, time.perf_counter() - start)
        for stale in folder.parent.glob(f".{folder.name}.*"):  # a killed writer's; no one else writes this key now
            shutil.rmtree(stale, ignore_errors=True)
        tmp = folder.parent / f".{folder.name}.{secrets.token_hex(6)}"
        tmp.mkdir()
        try:
            stream = stream_scenario(scenario)
            write(stream, fmt, tmp / NAMES[fmt])
            (tmp / "setup.json").write_text(json.dumps({"format": fmt, "scenario": stream.resolved()}, indent=2) + "\n")
            os.rename(tmp, folder)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return Recording(folder / NAMES[fmt], False, time.perf_counter() - start)


def write(scenario: Scenario, fmt: str, out: Path) -> None:
    """Simulate `scenario`'s sensor stream and write it as `fmt` at `out` (a fresh path inside a staging folder)."""
    from scenarios.export import FORMATS
    from scenarios.export.frames import open_stream

    info, frames = open_stream(scenario, estimates=False)
    if fmt == "nmea":
        with open(out, "w", newline="") as log:
            for frame in frames:
                for fix in frame.fixes:
                    if lines := fix.nmea():
                        log.write("\r\n".join(lines) + "\r\n")
        return
    if FORMATS[fmt].directory:
        out.mkdir()
    FORMATS[fmt].write(info, frames, out)
