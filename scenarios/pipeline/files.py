"""The run directory's data files: TUM trajectories, gps.csv, windows.csv, scans.csv, movers.csv.

TUM lines are 'timestamp tx ty tz qx qy qz qw' (world ENU, base_link, unit quaternion), the format
evo and the TUM RGB-D tools read; a pose the estimator did not have yet (before initialisation) is
left out, so every row is a real estimate.

Time: the run directory's TUM files carry UNIX time, seconds since 1970-01-01 UTC without leap seconds
(riverbench.unixtime), exact to the nanosecond ('%.9f'), as evo and ROS tools expect: the scenario's
time t is `[gnss] epoch_utc` + t. A comment line names the UNIX time of the scenario's time 0, so the
report (and `read_tum(..., scenario_time=True)`) can put the rows back on the scenario's clock, as
gps.csv, windows.csv and scans.csv keep it.
Height: the run's trajectories are written at the waterline (`waterline`: z = 0, the still water
surface that base_link's origin sits on), not with the wave heave nor an estimator's height: every
error the bench scores is horizontal (scenarios.score.metrics), so evo's default APE (3-D translation)
on these files is the bench's planar APE. The attitude (roll, pitch, yaw) is written as it is; the
bench's yaw error is heading only (evo's angle_deg also counts roll and pitch: equal in calm water).
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from riverbench.unixtime import parse_seconds_ns, seconds_text
from scenarios.pipeline.traffic_log import TrafficLog
from scenarios.score import windows as win
from scenarios.score.record import RunRecord

TUM_HEADER = "# timestamp tx ty tz qx qy qz qw\n"
TIME_ZERO = "# time zero (UNIX s):"
"""Starts the comment line that gives the UNIX time of the scenario's time 0 (stamps are UNIX seconds)."""


def waterline(poses: np.ndarray) -> np.ndarray:
    """The poses (N, 4, 4) with their origin moved to the still water surface (z = 0), attitude unchanged."""
    out = np.array(poses, dtype=float, copy=True)
    out[:, 2, 3] = 0.0
    return out


def write_tum(path: Path, t: np.ndarray, poses: np.ndarray, zero_ns: int | None = None) -> int:
    """Write the finite poses (N, 4, 4) at times t; returns the number of rows. With `zero_ns` (the UNIX nanoseconds
    of time 0) the stamps are written as UNIX seconds, exactly to the nanosecond, and a comment line says so;
    without it, as the seconds given."""
    ok = np.isfinite(poses).all(axis=(1, 2))
    with open(path, "w") as f:
        f.write(TUM_HEADER)
        if zero_ns is not None:
            f.write(f"{TIME_ZERO} {seconds_text(zero_ns)} (stamps: UNIX seconds, UTC; scenario time t is stamp - time zero)\n")
        if not ok.any():
            return 0
        stamps = [seconds_text(zero_ns + round(float(s) * 1e9)) if zero_ns is not None else f"{s:.9f}" for s in t[ok]]
        position = poses[ok, :3, 3]
        quaternion = Rotation.from_matrix(poses[ok, :3, :3]).as_quat()
        for stamp, p, q in zip(stamps, position, quaternion):
            f.write(f"{stamp} {p[0]:.6f} {p[1]:.6f} {p[2]:.6f} {q[0]:.9f} {q[1]:.9f} {q[2]:.9f} {q[3]:.9f}\n")
    return int(ok.sum())


def read_tum(path: Path, scenario_time: bool = False) -> np.ndarray:
    """(N, 8) rows of a TUM file ((0, 8) when it holds only the header, e.g. an estimator that never initialised).
    Stamps as written (UNIX seconds for a run's files); with `scenario_time`, seconds since the scenario's time 0,
    exact (a file without the time-zero line is taken to be on the scenario's clock already)."""
    zero, rows, stamps = 0, [], []
    for line in Path(path).read_text().splitlines():
        if line.startswith(TIME_ZERO):
            zero = parse_seconds_ns(line[len(TIME_ZERO) :].split()[0])
        elif line.strip() and not line.startswith("#"):
            fields = line.split()
            rows.append(fields)
            stamps.append(fields[0])
    out = np.array(rows, dtype=float).reshape(-1, 8)
    if scenario_time:
        out[:, 0] = [(parse_seconds_ns(s) - zero) / 1e9 for s in stamps]
    return out


def write_gps_csv(path: Path, rec: RunRecord, truth: bool = True) -> None:
    """One row per fix: time, reported position, quality, DOP, the true error (not when `truth` is False: a replay
    has none), and each estimator's verdict: trusted, statistic and the rule that refused it (empty where trusted)."""
    f = rec.fixes
    eids = list(f.trusted)
    header = ["t", "quality", "e", "n", "u", "lat", "lon", "alt", "num_sats", "hdop"]
    header += ["err_e", "err_n", "err_u", "err_h", "open_sky_err_h", "added_err_h", "nlos_used"] if truth else []
    header += [f"{e}.{k}" for e in eids for k in ("trusted", "statistic", "rule")]
    rules = {e: f.rule.get(e, np.full(len(f.t), "")) for e in eids}
    err_h, added = f.horizontal_error, f.added_error
    open_sky = np.hypot(f.open_sky_error[:, 0], f.open_sky_error[:, 1]) if len(f.t) else np.zeros(0)
    with open(path, "w", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(header)
        for i in range(len(f.t)):
            row = [
                f"{f.t[i]:.3f}",
                int(f.quality[i]),
                *_fmt(f.enu[i], 3),
                _fmt1(f.lat[i], 9),
                _fmt1(f.lon[i], 9),
                _fmt1(f.alt[i], 3),
                int(f.num_sats[i]),
                _fmt1(f.hdop[i], 2),
            ]
            if truth:
                row += [*_fmt(f.error[i], 3), _fmt1(err_h[i], 3), _fmt1(open_sky[i], 3), _fmt1(added[i], 3), int(f.nlos_used[i])]
            for e in eids:
                row += [int(f.trusted[e][i]), _fmt1(f.statistic[e][i], 4), rules[e][i]]
            w.writerow(row)


PASSAGE_KEYS = ("max_error", "entry_error", "exit_error", "added", "recover_s")
"""windows.csv's columns per estimator, `<id>.<key>`: its passage through the row's window (scenarios.score.windows.Passage)."""


def write_windows_csv(path: Path, windows: list[win.Window], rec: RunRecord, errors: dict[str, np.ndarray]) -> None:
    """One row per degradation window with each estimator's passage through it."""
    with open(path, "w", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(["kind", "start", "end", "duration"] + [f"{e}.{k}" for e in errors for k in PASSAGE_KEYS])
        for window in windows:
            row = [window.kind, f"{window.start:.3f}", f"{window.end:.3f}", f"{window.duration:.3f}"]
            for error in errors.values():
                row += passage_cells(window, rec.scan_t, error, win.next_start(window, windows))
            w.writerow(row)


def passage_cells(window: win.Window, t: np.ndarray, error: np.ndarray, until: float = math.inf) -> list[str]:
    """The PASSAGE_KEYS cells of windows.csv for an estimate with horizontal `error` at scan times `t` through `window`
    (`until`: the next window's start)."""
    p = win.passage(window, t, error, until)
    return [_fmt1(getattr(p, k), 3) for k in PASSAGE_KEYS]


def write_scans_csv(path: Path, rec: RunRecord) -> None:
    """One row per scan: the true pose (x, y, z, yaw), per matcher ok, gated, degenerate, points, ms, and per estimator that
    reports one its horizontal protection level (<id>.hpl, m; empty where it had none)."""
    mids = list(rec.matches)
    levels = {e: hpl for e, hpl in rec.protection.items() if np.isfinite(hpl).any()}
    with open(path, "w", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(
            ["t", "x", "y", "z", "yaw_deg"]
            + [f"{m}.{k}" for m in mids for k in ("ok", "gated", "degenerate", "points", "ms")]
            + [f"{e}.hpl" for e in levels]
        )
        yaw = np.degrees(np.arctan2(rec.truth[:, 1, 0], rec.truth[:, 0, 0])) if len(rec.scan_t) else np.zeros(0)
        for i, t in enumerate(rec.scan_t):
            row = [f"{t:.3f}", *_fmt(rec.truth[i, :3, 3], 3), f"{yaw[i]:.3f}"]
            for m in mids:
                track = rec.matches[m]
                row += [int(track.ok[i]), int(track.gated[i]), int(track.degenerate[i]), int(track.points[i]), f"{1e3 * track.seconds[i]:.2f}"]
            row += [f"{hpl[i]:.3f}" if np.isfinite(hpl[i]) else "" for hpl in levels.values()]
            w.writerow(row)


def write_vessel_csv(path: Path, log) -> None:
    """One row per control period (a revolution): the true plane pose, station, cross-track, clearance, nearest part, commands."""
    with open(path, "w", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(["t", "x", "y", "yaw_deg", "station_m", "cross_track_m", "clearance_m", "nearest_part", "cmd_left", "cmd_right"])
        for t, x, y, yaw, station, cross, clearance, part, left, right in log.rows:
            w.writerow([f"{t:.3f}", *_fmt((x, y), 3), f"{np.degrees(yaw):.3f}", *_fmt((station, cross, clearance), 3), part, *_fmt((left, right), 4)])


def write_movers_csv(path: Path, log: TrafficLog) -> None:
    """One row per scan and mover: t, id, the mover's LiDAR label, x, y (world ENU, m), yaw (deg from east)."""
    with open(path, "w", newline="") as handle:
        w = csv.writer(handle)
        w.writerow(["t", "id", "label", "x", "y", "yaw_deg"])
        for t, poses in zip(log.stamps, log.poses):
            for m, (mid, p) in enumerate(zip(log.traffic.ids, poses)):
                w.writerow(
                    [f"{t:.3f}", mid, log.first_label + m, f"{p[0, 3]:.3f}", f"{p[1, 3]:.3f}", f"{np.degrees(np.arctan2(p[1, 0], p[0, 0])):.3f}"]
                )


def _fmt1(value: float, digits: int) -> str:
    return "" if not np.isfinite(value) else f"{value:.{digits}f}"


def _fmt(values, digits: int) -> list[str]:
    return [_fmt1(float(v), digits) for v in values]
