"""A trajectory made outside the bench (a ROS or C++ stack run on an export) and the contract it is declared under: its
file read and checked, its stamps put on the run's clock.

Every problem is one line naming the file and what is wrong (ValueError), raised before anything is scored or written:
a missing or unreadable file, a line that is not 8 numbers (TUM: t tx ty tz qx qy qz qw) or 12 (KITTI: a 3x4 row-major
pose), a NaN or infinite number, a zero quaternion, stamps that do not strictly increase, a KITTI file without its
times file or with another line count, and stamps outside the run's span. For the last, the usual mistakes are
recognised and named: UNIX stamps declared as the run's clock (or the reverse, or seconds since the first scan as a
KITTI times.txt holds them), a whole-hour offset (a time zone), and the 18 s GPS-UTC leap-second offset.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal, get_args

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.spatial.transform import Rotation

from riverbench.unixtime import GPS_MINUS_UTC_S, NS_PER_S, parse_seconds_ns, seconds_text

Format = Literal["tum", "kitti"]
Frame = Literal["base_link", "lidar"]
Clock = Literal["unix", "run", "first_scan"]
Anchor = Literal["map", "first", "se2", "se3"]
NUMBERS = {"tum": 8, "kitti": 12}
"""Numbers per pose line of each format."""
LAYOUT = {"tum": "t tx ty tz qx qy qz qw", "kitti": "a 3x4 row-major pose r11 r12 r13 tx r21 r22 r23 ty r31 r32 r33 tz"}
CLOCK_WORDS = {
    "unix": "UNIX time",
    "run": "seconds on the run's clock",
    "first_scan": "seconds since the run's first scan (as a KITTI times.txt)",
}
HOURS = range(1, 15)
"""Whole-hour offsets recognised as a time-zone mistake (UTC-12 to UTC+14)."""


class Contract(BaseModel):
    """How an outside trajectory file is to be read and laid onto the run (DESIGN: format, frame, clock, anchor)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    format: Format = Field("tum", description="tum: 't tx ty tz qx qy qz qw' lines; kitti: 12 numbers a line (3x4 pose), stamps in `times`")
    times: Path | None = Field(None, description="kitti only: the file of one stamp per pose line")
    frame: Frame = Field("base_link", description="whose poses these are: the vessel's base_link, or the LiDAR's (moved by the run's mount)")
    clock: Clock = Field("unix", description="the stamps' clock: UNIX time, seconds on the run's clock, or seconds since its first scan")
    anchor: Anchor = Field(
        "map",
        description="map: poses in the run's map frame (scored as an estimator); first: odometry from its first pose, laid onto "
        "the truth there; se2, se3: odometry in any frame, moved by the rigid motion that best fits the truth (planar, or 3-D "
        "as evo's -a); first, se2 and se3 are scored as a matcher",
    )

    @classmethod
    def parse(cls, **options: object) -> Contract:
        """A contract from command-line values; a value outside its choices is one line naming the option and the choices."""
        for name, choices in (("format", Format), ("frame", Frame), ("clock", Clock), ("anchor", Anchor)):
            if options.get(name) is not None and options[name] not in get_args(choices):
                raise ValueError(f"--{name} {options[name]}: use {', '.join(get_args(choices))}")
        contract = cls.model_validate({k: v for k, v in options.items() if v is not None})
        if contract.format == "kitti" and contract.times is None:
            raise ValueError("--format kitti: give --times FILE, the stamp of each pose line (KITTI poses carry none)")
        if contract.format == "tum" and contract.times is not None:
            raise ValueError("--times is for --format kitti (a TUM line carries its own stamp)")
        return contract

    @property
    def section(self) -> str:
        """Where in metrics.json the trajectory is scored: 'estimators' (anchor map) or 'matchers' (odometry)."""
        return "estimators" if self.anchor == "map" else "matchers"


@dataclass(frozen=True)
class Trajectory:
    """An outside trajectory as its file gives it: stamps in integer nanoseconds of its own clock (N,) and poses (N, 4, 4)
    of its declared frame."""

    stamps_ns: np.ndarray
    poses: np.ndarray


@dataclass(frozen=True)
class Span:
    """The run a trajectory is scored into: its first scan and its end (seconds on its clock), the UNIX nanoseconds of its
    time 0, and how far a stamp may lie from a scan and still be that scan's (seconds)."""

    t_first: float
    t_end: float
    zero_ns: int
    tolerance_s: float

    def seconds(self, stamps_ns: np.ndarray, clock: str) -> np.ndarray:
        """Stamps of `clock` as seconds on the run's clock."""
        ns = np.asarray(stamps_ns, dtype=np.int64)
        if clock == "unix":
            return (ns - self.zero_ns) / NS_PER_S
        return ns / NS_PER_S + (self.t_first if clock == "first_scan" else 0.0)

    def holds(self, t: np.ndarray) -> bool:
        """Whether every time `t` (run clock) lies in the run, within the tolerance."""
        return bool(len(t)) and float(t.min()) >= self.t_first - self.tolerance_s and float(t.max()) <= self.t_end + self.tolerance_s


def read(path: Path, contract: Contract) -> Trajectory:
    """The trajectory file (and a KITTI file's times file) read and checked line by line."""
    lines = _lines(path)
    n = NUMBERS[contract.format]
    rows, stamps = [], []
    for number, line in lines:
        fields = line.split()
        if len(fields) != n:
            raise ValueError(f"{path} line {number}: {len(fields)} fields, not {n} numbers ({contract.format.upper()}: {LAYOUT[contract.format]})")
        values = [_number(path, number, f) for f in fields]
        rows.append(values)
        if contract.format == "tum":
            stamps.append(_stamp_ns(path, number, fields[0]))
    if not rows:
        raise ValueError(f"{path}: no pose lines (only comments or nothing)")
    table = np.array(rows, dtype=float)
    if contract.format == "tum":
        poses = _tum_poses(path, lines, table)
        _increasing(path, [number for number, _ in lines], stamps)
    else:
        assert contract.times is not None  # Contract.parse
        numbers, stamps = _times(contract.times, len(rows), path)
        poses = np.tile(np.eye(4), (len(rows), 1, 1))
        poses[:, :3, :] = table.reshape(-1, 3, 4)
        _increasing(contract.times, numbers, stamps)
    return Trajectory(np.array(stamps, dtype=np.int64), poses)


def on_run_clock(trajectory: Trajectory, path: Path, clock: str, span: Span) -> np.ndarray:
    """The stamps as seconds on the run's clock; outside the run, one line saying so and, when it sees it, why."""
    t = span.seconds(trajectory.stamps_ns, clock)
    if span.holds(t):
        return t
    raise ValueError(f"{path}: {_why_outside(trajectory.stamps_ns, clock, span, t)}")


def _why_outside(stamps_ns: np.ndarray, clock: str, span: Span, t: np.ndarray) -> str:
    """The sentence on stamps outside the run: a recognised mistake named, else where they lie against the run."""
    run = f"the run spans {span.t_first:.3f} … {span.t_end:.3f} s on its clock"
    for other in [clock, *(c for c in get_args(Clock) if c != clock)]:
        for shift_s, what in _offsets():
            if (other, shift_s) == (clock, 0.0) or not span.holds(span.seconds(stamps_ns, other) - shift_s):
                continue
            said = []
            if other != clock:
                said.append(f"the stamps are {CLOCK_WORDS[other]}, not {CLOCK_WORDS[clock]} (--clock {clock}): declare --clock {other}")
            if shift_s:
                said.append(f"the stamps are {abs(shift_s):g} s {'late' if shift_s > 0 else 'early'} ({what})")
            return f"{' and '.join(said)}; {run}"
    outside = int(np.sum((t < span.t_first - span.tolerance_s) | (t > span.t_end + span.tolerance_s)))
    return f"{outside} of {len(t)} stamps lie outside the run: {t.min():.3f} … {t.max():.3f} s read as {CLOCK_WORDS[clock]}, but {run}"


def _offsets() -> list[tuple[float, str]]:
    """Clock offsets a stamp file commonly has, as (seconds the stamps are late, what it is), the plain one first."""
    leap = f"GPS time, not UTC: GPS - UTC = {GPS_MINUS_UTC_S} leap seconds"
    out: list[tuple[float, str]] = [(0.0, ""), (float(GPS_MINUS_UTC_S), leap), (-float(GPS_MINUS_UTC_S), f"UTC taken for GPS time? {leap}")]
    for hours in HOURS:
        for sign in (1, -1):
            out.append((sign * 3600.0 * hours, f"{hours} h off: a time-zone offset? UNIX time is UTC"))
    return out


def _lines(path: Path) -> list[tuple[int, str]]:
    """(line number, text) of each line that is not blank and not a '#' comment."""
    try:
        text = Path(path).read_text()
    except FileNotFoundError:
        raise ValueError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: cannot read it ({getattr(exc, 'strerror', None) or exc})") from None
    return [(i, line) for i, line in enumerate(text.splitlines(), start=1) if line.strip() and not line.lstrip().startswith("#")]


def _number(path: Path, line: int, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{path} line {line}: {text!r} is not a number") from None
    if not math.isfinite(value):
        raise ValueError(f"{path} line {line}: {text} is not a finite number")
    return value


def _stamp_ns(path: Path, line: int, text: str) -> int:
    """A stamp as integer nanoseconds: exact for decimal text, else (exponent notation) from its float."""
    try:
        return parse_seconds_ns(text)
    except ValueError:
        return round(_number(path, line, text) * NS_PER_S)


def _tum_poses(path: Path, lines: list[tuple[int, str]], table: np.ndarray) -> np.ndarray:
    quaternion = table[:, 4:8]
    norm = np.linalg.norm(quaternion, axis=1)
    if (bad := np.nonzero(norm < 1e-9)[0]).size:
        raise ValueError(f"{path} line {lines[bad[0]][0]}: the quaternion qx qy qz qw is zero (no rotation)")
    poses = np.tile(np.eye(4), (len(table), 1, 1))
    poses[:, :3, :3] = Rotation.from_quat(quaternion / norm[:, None]).as_matrix()
    poses[:, :3, 3] = table[:, 1:4]
    return poses


def _times(path: Path, count: int, poses_path: Path) -> tuple[list[int], list[int]]:
    """A KITTI times file's line numbers and stamps (ns): one stamp a line, as many as pose lines."""
    lines = _lines(path)
    for number, line in lines:
        if len(line.split()) != 1:
            raise ValueError(f"{path} line {number}: {len(line.split())} fields, not one stamp")
        _number(path, number, line.strip())
    if len(lines) != count:
        raise ValueError(f"{path} has {len(lines)} stamps but {poses_path} {count} poses: a times file gives one stamp per pose line")
    return [number for number, _ in lines], [_stamp_ns(path, number, line.strip()) for number, line in lines]


def _increasing(path: Path, numbers: list[int], stamps: list[int]) -> None:
    steps = np.diff(np.asarray(stamps, dtype=np.int64))
    if (bad := np.nonzero(steps <= 0)[0]).size:
        i = int(bad[0]) + 1
        raise ValueError(
            f"{path} line {numbers[i]}: stamp {seconds_text(stamps[i])} is not after the previous one ({seconds_text(stamps[i - 1])}): "
            "stamps must increase strictly"
        )
