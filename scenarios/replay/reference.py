"""A reference trajectory a replay is scored against (`replay --reference FILE`): accuracy instead of agreement with GPS.

Formats (by content):
- TUM (`t x y z qx qy qz qw` rows, '#' comments): t in UNIX seconds, x y z in the replay's ENU
  frame (metres.json's run.recording.origin: the world's origin or the recording's first fix),
  the pose of base_link (what riverbench writes as groundtruth.tum);
- GPX 1.0/1.1 (read with the standard library's xml.etree): every track point (trkpt) with a
  <time>, its lat, lon and ele (none: the origin's height), a position of the reference
  receiver's antenna;
- an NMEA log of an RTK receiver: its RTK fixed and float epochs only (GGA quality 4 or 5, as
  sim.nmea.epochs reads them; scenarios.replay.nmea_log stamps them), the antenna's position.
Samples are sorted by time (a repeated time keeps its first); the reference is interpolated
linearly between two samples at most `max_gap_s` apart (GAP_FACTOR times its median step), never
across a longer gap.

Scoring (`score`): at every time the estimates were sampled (scans, or a GNSS-only replay's fixes)
where the reference is defined, the horizontal distance from the estimate (its antenna, base_link
pose times the scenario's antenna offset, for an antenna reference; base_link for TUM) to the
reference: `ape` (rmse, mean, median, p95, max), `available` (share of those times with an
estimate), `scored` (how many), and `blackout`: the same errors through the recording's GPS
blackouts (runs of fixes with no measured position, GGA quality not 1, 2, 4 or 5, each to the next
measured fix) as scenarios.score.metrics.window_metrics gives them for a simulated run (count,
seconds, max_error, exit_error, added, recover_s, recovered).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from fusion.observation import POSITION_QUALITIES
from scenarios.replay import nmea_log
from scenarios.replay.recording import Geo, LogStats, Place, Recording, unix_ns
from scenarios.score import metrics
from scenarios.score import windows as win
from scenarios.score.record import FixTable, RunRecord

RTK_QUALITIES = (4, 5)
"""GGA quality of RTK fixed and RTK float solutions: the epochs an NMEA reference contributes."""
GAP_FACTOR = 3.0


@dataclass(frozen=True)
class Reference:
    """Reference positions: replay times (s, increasing), ENU positions (N, 3), which point of the boat they are, its format."""

    path: Path
    format: str
    point: str
    t: np.ndarray
    enu: np.ndarray

    @property
    def max_gap_s(self) -> float:
        """The longest step interpolated across."""
        return GAP_FACTOR * float(np.median(np.diff(self.t))) if len(self.t) > 1 else 0.0

    def at(self, t: np.ndarray) -> np.ndarray:
        """(len(t), 2) reference east, north at times t; NaN outside it or within a gap longer than max_gap_s."""
        t = np.asarray(t, dtype=float)
        out = np.full((len(t), 2), np.nan)
        if len(self.t) == 1:
            out[t == self.t[0]] = self.enu[0, :2]
            return out
        k = np.clip(np.searchsorted(self.t, t, side="right"), 1, len(self.t) - 1)
        inside = (t >= self.t[0]) & (t <= self.t[-1]) & (self.t[k] - self.t[k - 1] <= self.max_gap_s + 1e-9)
        for axis in (0, 1):
            out[inside, axis] = np.interp(t[inside], self.t, self.enu[:, axis])
        return out

    def overlap(self, recording: Recording) -> None:
        """ValueError (one line) when the reference does not overlap the recording in time."""
        geo = recording.geo
        if self.t[-1] < recording.t_start or self.t[0] > recording.t_end:
            raise ValueError(
                f"{self.path}: the reference spans {geo.utc(self.t[0]):%Y-%m-%d %H:%M:%S} to {geo.utc(self.t[-1]):%H:%M:%S} UTC, "
                f"the recording {geo.utc(recording.t_start):%Y-%m-%d %H:%M:%S} to {geo.utc(recording.t_end):%H:%M:%S}: "
                "they do not overlap"
            )

    def tree(self) -> dict:
        """What metrics.json says about the reference."""
        return {"path": str(self.path), "format": self.format, "point": self.point, "samples": len(self.t), "t_start": self.t[0], "t_end": self.t[-1]}


def read(path: str | Path, geo: Geo, place: Place) -> Reference:
    """The reference at `path` in the replay's time base and ENU frame; ValueError (one line) when it cannot be read or is empty."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such reference file")
    head = path.read_bytes()[:4096].lstrip()
    if head.startswith(b"<"):
        fmt, point, t, enu = "GPX", "antenna", *gpx(path, geo)
    elif nmea_log.is_log(path):
        fmt, point, t, enu = "RTK NMEA", "antenna", *rtk(path, geo, place)
    else:
        fmt, point, t, enu = "TUM", "base_link", *tum(path, geo)
    if not len(t):
        raise ValueError(f"{path}: no reference sample in this {fmt} file")
    order = np.argsort(t, kind="stable")
    t, enu = t[order], enu[order]
    keep = np.r_[True, np.diff(t) > 0]
    return Reference(path, fmt, point, t[keep], enu[keep])


def tum(path: Path, geo: Geo) -> tuple[np.ndarray, np.ndarray]:
    """Times and positions of a TUM file's rows."""
    rows = []
    for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
        text = line.strip()
        if not text or text.startswith("#"):
            continue
        try:
            values = [float(v) for v in text.split()]
        except ValueError:
            values = []
        if len(values) != 8 or not all(math.isfinite(v) for v in values):
            raise ValueError(f"{path}: line {number} is not a TUM row (t x y z qx qy qz qw): {text[:60]!r}")
        rows.append(values)
    data = np.array(rows, dtype=float).reshape(-1, 8)
    return np.array([geo.seconds(round(t * 1e9)) for t in data[:, 0]]), data[:, 1:4]


def gpx(path: Path, geo: Geo) -> tuple[np.ndarray, np.ndarray]:
    """Times and ENU positions of a GPX file's timed track points."""
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ValueError(f"{path}: not a readable GPX file ({exc})") from None
    t, enu = [], []
    for point in root.iter():
        if not point.tag.endswith("trkpt"):
            continue
        children = {child.tag.rsplit("}", 1)[-1]: (child.text or "").strip() for child in point}
        try:
            lat, lon = float(point.attrib["lat"]), float(point.attrib["lon"])
            when = datetime.fromisoformat(children["time"])
            height = float(children["ele"]) if children.get("ele") else geo.origin[2]
        except (KeyError, ValueError):
            continue
        when = when if when.tzinfo is not None else when.replace(tzinfo=UTC)
        t.append(geo.seconds(unix_ns(when)))
        enu.append(geo.enu(lat, lon, height))
    return np.array(t, dtype=float), np.array(enu, dtype=float).reshape(-1, 3)


def rtk(path: Path, geo: Geo, place: Place) -> tuple[np.ndarray, np.ndarray]:
    """Times and ENU positions of an NMEA log's RTK fixed and float epochs."""
    t, enu = [], []
    for ns, epoch in nmea_log.stamped(path, place.epoch_utc.date(), LogStats()):
        if epoch.quality in RTK_QUALITIES and math.isfinite(epoch.lat):
            t.append(geo.seconds(ns))
            enu.append(geo.enu(epoch.lat, epoch.lon, epoch.alt if math.isfinite(epoch.alt) else geo.origin[2]))
    if not t:
        raise ValueError(f"{path}: no RTK fixed or float epoch (GGA quality 4 or 5) to use as a reference")
    return np.array(t, dtype=float), np.array(enu, dtype=float).reshape(-1, 3)


def blackouts(fixes: FixTable) -> list[win.Window]:
    """The recording's GPS blackouts: each run of fixes with no measured position, to the next measured fix (or the last fix)."""
    measured = np.isin(fixes.quality, sorted(POSITION_QUALITIES))
    out, start = [], None
    for t, ok in zip(fixes.t, measured):
        if not ok and start is None:
            start = float(t)
        elif ok and start is not None:
            out.append(win.Window("blackout", start, float(t)))
            start = None
    if start is not None and len(fixes.t):
        out.append(win.Window("blackout", start, float(fixes.t[-1])))
    return out


def score(rec: RunRecord, eid: str, reference: Reference, antenna: np.ndarray) -> dict:
    """An estimator's errors against the reference (module docstring)."""
    est = rec.estimates[eid]
    where = reference.at(rec.scan_t)
    defined = np.isfinite(where).all(axis=1)
    has = np.isfinite(est).all(axis=(1, 2))
    point = est[:, :3, :3] @ antenna + est[:, :3, 3] if reference.point == "antenna" else est[:, :3, 3]
    error = np.where(defined & has, np.hypot(*(point[:, :2] - where).T), np.nan)
    return {
        "available": float(has[defined].mean()) if defined.any() else math.nan,
        "scored": int(defined.sum()),
        "ape": metrics.stats(error),
        "blackout": metrics.window_metrics(blackouts(rec.fixes), rec.scan_t, error)["blackout"],
    }
