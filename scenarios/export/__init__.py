"""Export a scenario's simulated sensor stream for outside tools (`riverbench export`).

    export("quickstart", "kitti", "out/kitti", progress=lambda done, total: ...) -> ExportResult

Formats (see each module for the exact layout):
    kitti  directory: KITTI odometry, velodyne/*.bin (x y z reflectance), times.txt, calib.txt, poses (kitti.py)
    pcd    directory: a binary PCD per scan (x y z intensity ring time), times.txt, poses.txt (pointfiles.py)
    ply    directory: a binary PLY per scan (same fields), times.txt, poses.txt (pointfiles.py)
    pcap   file: the HDL-32E's UDP data packets and GPRMC position packets, as the sensor streams them (pcap.py)
    rosbag2 directory: a rosbag2 bag, sqlite3 storage: PointCloud2, NavSatFix, NMEA, the mounts on /tf_static, truth
           and each estimator's output as nav_msgs/Odometry (rosbag.py; the estimators run during the export); Imu and
           MagneticField when the scenario simulates an IMU and a compass
    mcap   directory: the same rosbag2 bag, MCAP storage (rosbag.py)

Frames are simulated and written one at a time; the output appears at `out` only when complete.
"""

from __future__ import annotations

import os
import secrets
import shutil
import time
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import scenarios
from riverbench.atomic import atomic_path
from scenarios.export import kitti, pcap, pointfiles, rosbag
from scenarios.export.frames import Frame, StreamInfo, open_stream

Writer = Callable[[StreamInfo, Iterable[Frame], Path], dict[str, int]]
Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class Format:
    """A registered export: its writer and whether it writes a directory or a single file.

    A writer gets (info, frames, tmp): tmp is a fresh empty directory (or file) that becomes `out` once
    the writer returns; it takes the frames one at a time and returns its counts, e.g. {"points": n}.
    A format with `estimates` gets frames carrying the scenario's estimator outputs (its matchers and
    estimators run during the export, as `riverbench run` runs them)."""

    write: Writer
    directory: bool = True
    estimates: bool = False


FORMATS: dict[str, Format] = {
    "kitti": Format(kitti.write),
    "pcd": Format(pointfiles.write_pcd),
    "ply": Format(pointfiles.write_ply),
    "pcap": Format(pcap.write, directory=False),
    "rosbag2": Format(rosbag.write_sqlite3, estimates=True),
    "mcap": Format(rosbag.write_mcap, estimates=True),
}


@dataclass(frozen=True)
class ExportResult:
    """What an export wrote: where, how many scans, how long it took and the writer's own counts."""

    out: Path
    format: str
    scans: int
    seconds: float
    counts: dict[str, int] = field(default_factory=dict)


def export(
    source: str | Path, fmt: str, out: str | Path, *, set: list[str] | None = None, seed: int | None = None, progress: Progress | None = None
) -> ExportResult:
    """Simulate `source` (library name, .toml or run directory) and write it as `fmt` at `out`, all or nothing."""
    if fmt not in FORMATS:
        raise ValueError(f"unknown export format {fmt!r}; the formats are: {', '.join(FORMATS)}")
    out = Path(out)
    check_out(out, FORMATS[fmt].directory)
    start = time.perf_counter()
    info, frames = open_stream(scenarios.load(scenario_file(source), set=set, seed=seed), estimates=FORMATS[fmt].estimates)
    metered = _Metered(frames, info.scans, progress)
    with staged_dir(out) if FORMATS[fmt].directory else atomic_path(out) as tmp:
        counts = FORMATS[fmt].write(info, metered, tmp)
    return ExportResult(out, fmt, metered.done, time.perf_counter() - start, counts)


def scenario_file(source: str | Path) -> str | Path:
    """The scenario to load: a run directory's scenario.toml, else `source` itself (a name or a .toml)."""
    path = Path(source)
    if path.is_dir():
        if not (path / "scenario.toml").is_file():
            raise ValueError(f"{path} is a directory without scenario.toml, not a run directory")
        return path / "scenario.toml"
    return source


def check_out(out: Path, directory: bool) -> None:
    """Refuse to write over anything: an existing file, or a non-empty directory."""
    if directory and out.is_dir():
        if any(out.iterdir()):
            raise ValueError(f"output directory {out} is not empty")
    elif out.exists():
        raise ValueError(f"output {out} already exists")


class _Metered:
    """The frames, counted and reported to `progress(done, total)` as the writer takes each one."""

    def __init__(self, frames: Iterator[Frame], total: int, progress: Progress | None) -> None:
        self._frames = frames
        self._total = total
        self._progress = progress
        self.done = 0

    def __iter__(self) -> Iterator[Frame]:
        """Yield the frames lazily, counting each one once the writer comes back for the next."""
        for frame in self._frames:
            yield frame
            self.done += 1
            if self._progress is not None:
                self._progress(self.done, self._total)


@contextmanager
def staged_dir(out: Path) -> Iterator[Path]:
    """A fresh hidden sibling of `out`, renamed onto it (replacing an empty one) only when the block succeeds."""
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.{secrets.token_hex(6)}"
    tmp.mkdir()  # not mkdtemp: its 0700 mode would outlive the rename
    try:
        yield tmp
        if out.is_dir():
            out.rmdir()
        os.replace(tmp, out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
