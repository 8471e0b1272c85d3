"""What a run keeps: a few numbers per scan and per fix (never a scan), as columns, and the
matchers' odometry chained from the true start pose, so metrics and files can be computed at the end."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fusion.observation import POSITION_QUALITIES
from matcher.result import MatchResult
from sim.gnss_fix import GnssFix


@dataclass
class MatcherTrack:
    """Per scan: ok, gated (dropped by the point-count gate), degenerate, points, seconds, and the
    chained base_link pose (N, 4, 4) in the world (odometry from the true start pose)."""

    ok: np.ndarray
    gated: np.ndarray
    degenerate: np.ndarray
    points: np.ndarray
    seconds: np.ndarray
    pose: np.ndarray


@dataclass
class FixTable:
    """Per fix: what the receiver reported, its true error, and each estimator's verdict."""

    t: np.ndarray
    quality: np.ndarray
    enu: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    alt: np.ndarray
    num_sats: np.ndarray
    hdop: np.ndarray
    error: np.ndarray
    open_sky_error: np.ndarray
    nlos_used: np.ndarray
    trusted: dict[str, np.ndarray]
    statistic: dict[str, np.ndarray]
    rule: dict[str, np.ndarray] = field(default_factory=dict)
    """Per estimator, the rule that refused each fix (fusion.Verdict.rule; "" where trusted)."""

    @property
    def measured(self) -> np.ndarray:
        """Fixes with a measured position (GGA quality 1, 2, 4 or 5: autonomous, SBAS/DGPS, RTK fixed or float; not the
        receiver's dead reckoning)."""
        return np.isin(self.quality, sorted(POSITION_QUALITIES))

    @property
    def horizontal_error(self) -> np.ndarray:
        return np.hypot(self.error[:, 0], self.error[:, 1])

    @property
    def added_error(self) -> np.ndarray:
        """Horizontal norm of what the environment added to the open-sky error (blockage, reflections, faults)."""
        d = self.error - self.open_sky_error
        return np.hypot(d[:, 0], d[:, 1])


@dataclass
class HeadingTable:
    """Per compass output: its heading and the true one (rad, ENU yaw), and whether each estimator fed it used it."""

    t: np.ndarray
    measured: np.ndarray
    truth: np.ndarray
    used: dict[str, np.ndarray]

    @property
    def error(self) -> np.ndarray:
        """The compass's heading error, rad, wrapped to [-pi, pi)."""
        return (self.measured - self.truth + np.pi) % (2.0 * np.pi) - np.pi


@dataclass
class RunRecord:
    """A finished run's columns. scan_t (N,), truth (N, 4, 4) world<-base_link, estimates[id] (N, 4, 4)
    (NaN before initialisation or after a failure), matches[id], fixes, failures (component, id,
    stamp, reason), injected (start, end) GPS faults."""

    scan_t: np.ndarray
    truth: np.ndarray
    estimates: dict[str, np.ndarray]
    matches: dict[str, MatcherTrack]
    fixes: FixTable
    failures: list[dict] = field(default_factory=list)
    injected: list[tuple[float, float]] = field(default_factory=list)
    headings: HeadingTable | None = None
    protection: dict[str, np.ndarray] = field(default_factory=dict)
    """Per estimator, its horizontal protection level at each scan (m; NaN where it reported none)."""


class Column:
    """Rows of one shape and dtype in numpy blocks of BLOCK rows: a row costs its bytes (no Python
    object each, no doubling slack, no copy while recording), so a long run's record stays small."""

    BLOCK = 4096

    def __init__(self, row: np.ndarray) -> None:
        self._blocks = [np.empty((self.BLOCK, *row.shape), dtype=row.dtype)]
        self._n = 0  # rows in the last block

    def append(self, row: np.ndarray) -> None:
        if self._n == len(self._blocks[-1]):
            self._blocks.append(np.empty((self.BLOCK, *row.shape), dtype=self._blocks[-1].dtype))
            self._n = 0
        self._blocks[-1][self._n] = row
        self._n += 1

    def array(self) -> np.ndarray:
        """All rows as one array (the blocks are merged once and released)."""
        merged = np.concatenate([*self._blocks[:-1], self._blocks[-1][: self._n]])
        self._blocks, self._n = [merged], len(merged)
        return merged


class Recorder:
    """Collects a run's columns as it streams."""

    def __init__(self, matcher_ids: list[str], estimator_ids: list[str], mount: np.ndarray) -> None:
        self.matcher_ids, self.estimator_ids = matcher_ids, estimator_ids
        self.mount, self.mount_inv = mount, np.linalg.inv(mount)
        self.scan_rows: dict[str, Column] = {}
        self.fix_rows: dict[str, Column] = {}
        self.heading_rows: dict[str, Column] = {}
        self.failures: list[dict] = []
        self._rules: dict[str, int] = {"": 0}  # each refusing rule seen, by its index in the fix rows (few distinct ones)
        self._lidar_at: dict[str, dict[float, np.ndarray]] = {m: {} for m in matcher_ids}
        self._latest_ref: dict[str, np.ndarray | None] = {m: None for m in matcher_ids}

    def _add(self, rows: dict[str, Column], key: str, value) -> None:
        row = np.asarray(value)
        if key not in rows:
            rows[key] = Column(row)
        rows[key].append(row)

    def scan(
        self,
        stamp: float,
        truth: np.ndarray,
        results: dict[str, MatchResult],
        estimates: dict[str, np.ndarray],
        levels: dict[str, float] | None = None,
    ) -> None:
        """One scan: true base_link pose, every matcher's result, every estimator's pose after it and its horizontal
        protection level (NaN: none reported)."""
        self._add(self.scan_rows, "t", stamp)
        self._add(self.scan_rows, "truth", truth)
        for mid, r in results.items():
            self._add(self.scan_rows, f"ok:{mid}", bool(r.ok))
            self._add(self.scan_rows, f"gated:{mid}", bool(r.info.get("gated", False)))
            self._add(self.scan_rows, f"degenerate:{mid}", bool(r.info.get("degenerate", False)) and bool(r.ok))
            self._add(self.scan_rows, f"points:{mid}", int(r.n_points))
            self._add(self.scan_rows, f"seconds:{mid}", float(r.seconds))
            self._add(self.scan_rows, f"pose:{mid}", self._chain(mid, stamp, truth, r))
        for eid, pose in estimates.items():
            self._add(self.scan_rows, f"est:{eid}", pose)
            self._add(self.scan_rows, f"hpl:{eid}", float((levels or {}).get(eid, math.nan)))

    def _chain(self, mid: str, stamp: float, truth: np.ndarray, r: MatchResult) -> np.ndarray:
        """World<-base_link of this scan from the matcher's odometry. A scan that passed the gate becomes
        the reference (a failed match holds the reference's pose: that motion is lost); a gated scan
        holds the latest reference's pose and is not a reference (before the first reference: no
        odometry yet, NaN; the matcher's first reference is its first scan that passes the gate)."""
        known = self._lidar_at[mid]
        if r.info.get("gated", False):
            return nan_pose() if self._latest_ref[mid] is None else self._latest_ref[mid] @ self.mount_inv
        if self._latest_ref[mid] is None:
            lidar = truth @ self.mount  # the start pose: odometry is chained from the truth here
        else:
            ref = known.get(r.info.get("ref_stamp"), self._latest_ref[mid])
            lidar = ref @ np.asarray(r.T, dtype=float) if r.ok else ref
        known.clear()  # only the latest reference is ever referred to
        known[stamp] = lidar
        self._latest_ref[mid] = lidar
        return lidar @ self.mount_inv

    def fix(self, fix: GnssFix, verdicts: dict[str, tuple[bool, float, str]]) -> None:
        """One receiver epoch with each estimator's (trusted, statistic, the rule that refused it or "")."""
        add = lambda k, v: self._add(self.fix_rows, k, v)
        truth = fix.truth
        nan3 = np.full(3, np.nan)
        add("t", fix.stamp)
        add("quality", int(fix.quality))
        add("enu", np.asarray(fix.enu, dtype=float) if fix.quality else nan3)
        add("lat", fix.lat)
        add("lon", fix.lon)
        add("alt", fix.alt)
        add("num_sats", int(fix.num_sats))
        add("hdop", float(fix.hdop))
        add("error", np.asarray(truth.error, dtype=float) if truth is not None and fix.quality else nan3)
        add("open_sky_error", np.asarray(truth.open_sky_error, dtype=float) if truth is not None else nan3)
        nlos = {(s.system, s.prn) for s in truth.sats if s.nlos} if truth is not None else set()
        add("nlos_used", bool(fix.quality in POSITION_QUALITIES and any(s.used and (s.system, s.prn) in nlos for s in fix.sats)))
        for eid, (trusted, statistic, rule) in verdicts.items():
            add(f"trusted:{eid}", bool(trusted))
            add(f"stat:{eid}", float(statistic))
            add(f"rule:{eid}", self._rules.setdefault(str(rule), len(self._rules)))

    def heading(self, stamp: float, measured: float, truth: float, used: dict[str, bool]) -> None:
        """One compass output: its heading, the true heading and whether each estimator fed it used it."""
        self._add(self.heading_rows, "t", stamp)
        self._add(self.heading_rows, "measured", measured)
        self._add(self.heading_rows, "truth", truth)
        for eid, ok in used.items():
            self._add(self.heading_rows, f"used:{eid}", bool(ok))

    def failure(self, component: str, cid: str, stamp: float, reason: str) -> None:
        self.failures.append({"component": component, "id": cid, "stamp": float(stamp), "reason": reason})

    def finish(self, injected: list[tuple[float, float]]) -> RunRecord:
        s, f = self.scan_rows, self.fix_rows

        def col(rows, key, shape=(0,), dtype=float):
            return rows[key].array().astype(dtype, copy=False) if key in rows else np.zeros(shape, dtype=dtype)

        matches = {
            m: MatcherTrack(
                col(s, f"ok:{m}", dtype=bool),
                col(s, f"gated:{m}", dtype=bool),
                col(s, f"degenerate:{m}", dtype=bool),
                col(s, f"points:{m}", dtype=int),
                col(s, f"seconds:{m}"),
                col(s, f"pose:{m}", (0, 4, 4)),
            )
            for m in self.matcher_ids
        }
        fixes = FixTable(
            t=col(f, "t"),
            quality=col(f, "quality", dtype=int),
            enu=col(f, "enu", (0, 3)),
            lat=col(f, "lat"),
            lon=col(f, "lon"),
            alt=col(f, "alt"),
            num_sats=col(f, "num_sats", dtype=int),
            hdop=col(f, "hdop"),
            error=col(f, "error", (0, 3)),
            open_sky_error=col(f, "open_sky_error", (0, 3)),
            nlos_used=col(f, "nlos_used", dtype=bool),
            trusted={e: col(f, f"trusted:{e}", dtype=bool) for e in self.estimator_ids},
            statistic={e: col(f, f"stat:{e}") for e in self.estimator_ids},
            rule={e: np.array(list(self._rules), dtype=str)[col(f, f"rule:{e}", dtype=int)] for e in self.estimator_ids},
        )
        return RunRecord(
            scan_t=col(s, "t"),
            truth=col(s, "truth", (0, 4, 4)),
            estimates={e: col(s, f"est:{e}", (0, 4, 4)) for e in self.estimator_ids},
            matches=matches,
            fixes=fixes,
            failures=list(self.failures),
            injected=list(injected),
            headings=self._headings(),
            protection={e: col(s, f"hpl:{e}") for e in self.estimator_ids},
        )

    def _headings(self) -> HeadingTable | None:
        h = self.heading_rows
        if "t" not in h:
            return None
        used = {k.split(":", 1)[1]: h[k].array().astype(bool) for k in h if k.startswith("used:")}
        return HeadingTable(h["t"].array(), h["measured"].array(), h["truth"].array(), used)


def nan_pose() -> np.ndarray:
    return np.full((4, 4), math.nan)
