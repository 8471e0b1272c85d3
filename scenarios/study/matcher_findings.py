"""Findings e-h measured on the matchers: rate and precision (e), success against points per scan (f), outlier shares
(g) from the bursts of consecutive revolutions, and the yaw drift of one matcher's chained odometry (h)."""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import spearmanr

from riverbench.angles import wrap_angle
from scenarios.score import metrics
from scenarios.study.tasks import OUTLIER_KEYS, ChainPiece

BIN_POINTS = 1000
"""Width of a points-per-scan bin in the success curve."""


def columns(rows: list[dict], mid: str) -> dict[str, np.ndarray]:
    """The burst rows of one matcher as columns (NaN where a row lacks a diagnostic)."""
    mine = [r for r in rows if r["matcher"] == mid]
    keys = ("t", "ok", "gated", "points", "seconds", "cpu_seconds", "error_m", "yaw_error_deg", *OUTLIER_KEYS)
    return {k: np.array([r.get(k, math.nan) for r in mine], dtype=float) for k in keys}


def rates(rows: list[dict], mids: list[str]) -> dict:
    """Finding e, per matcher: registrations, Hz (1 / median wall time of the registered, not gated, ones; cpu_hz from
    the process's CPU time instead, steadier on a loaded machine), success and
    unresolved shares, median translation and yaw error of the ok matches against the exact relative motion, and the
    Spearman correlation of the wall time, and of the CPU time, with the points per scan."""
    out = {}
    for mid in mids:
        c = columns(rows, mid)
        reg = c["gated"] == 0
        sec, pts, cpu = c["seconds"][reg], c["points"][reg], c["cpu_seconds"][reg]
        ok = c["ok"] == 1
        out[mid] = {
            "registrations": int(len(c["t"])),
            "hz": float(1.0 / np.median(sec)) if len(sec) and np.median(sec) > 0 else math.nan,
            "ms_median": float(1e3 * np.median(sec)) if len(sec) else math.nan,
            "cpu_hz": float(1.0 / np.median(cpu)) if len(cpu) and np.median(cpu) > 0 else math.nan,
            "success": float(ok.mean()) if len(ok) else math.nan,
            "unresolved": float(1.0 - ok.mean()) if len(ok) else math.nan,
            "error_m_median": float(np.median(c["error_m"][ok])) if ok.any() else math.nan,
            "yaw_error_deg_median": float(np.median(c["yaw_error_deg"][ok])) if ok.any() else math.nan,
            "points_median": float(np.median(c["points"])) if len(c["points"]) else math.nan,
            "spearman_seconds_points": float(spearmanr(sec, pts).statistic) if len(sec) >= 3 and np.ptp(pts) > 0 else math.nan,
            "spearman_cpu_seconds_points": float(spearmanr(cpu, pts).statistic) if len(cpu) >= 3 and np.ptp(pts) > 0 else math.nan,
        }
    return out


def success_curve(rows: list[dict], mids: list[str], band: tuple[int, int]) -> dict:
    """Finding f, per matcher: success rate and count per points-per-scan bin (BIN_POINTS wide), and over the study's
    band and below it."""
    top = max([r["points"] for r in rows] + [band[1]])
    edges = np.arange(0, (top // BIN_POINTS + 2) * BIN_POINTS, BIN_POINTS)  # the last bin holds the largest scan
    out: dict = {"bin_edges": edges.tolist(), "band": list(band), "matchers": {}}
    for mid in mids:
        c = columns(rows, mid)
        ok, pts = c["ok"] == 1, c["points"]
        idx = np.digitize(pts, edges) - 1
        counts = np.bincount(idx, minlength=len(edges) - 1)[: len(edges) - 1] if len(pts) else np.zeros(len(edges) - 1, int)
        wins = np.bincount(idx, weights=ok, minlength=len(edges) - 1)[: len(edges) - 1] if len(pts) else np.zeros(len(edges) - 1)
        in_band, below = (pts >= band[0]) & (pts <= band[1]), pts < band[0]
        out["matchers"][mid] = {
            "count": counts.astype(int).tolist(),
            "success": [float(w / n) if n else None for w, n in zip(wins, counts)],
            "band_count": int(in_band.sum()),
            "band_success": float(ok[in_band].mean()) if in_band.any() else math.nan,
            "below_count": int(below.sum()),
            "below_success": float(ok[below].mean()) if below.any() else math.nan,
        }
    return out


def tilt_change(trajectory, starts: np.ndarray, revolution_s: float) -> dict:
    """How far the LiDAR tilts between the first two revolutions of each burst (the angle between its vertical axes one
    revolution apart, deg; median and p90): zero on glassy water, where consecutive revolutions cross every surface along
    the same lines, and a fraction of a degree in a chop, where a ring meets a wall 80 m off 0.2 m higher or lower per
    0.15 deg."""
    if not len(starts):
        return {"median": math.nan, "p90": math.nan, "n": 0}
    t = np.asarray(starts, dtype=float)
    a, b = trajectory.lidar_poses(t)[:, :3, 2], trajectory.lidar_poses(t + revolution_s)[:, :3, 2]
    angle = np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", a, b), -1.0, 1.0)))
    return {"median": float(np.median(angle)), "p90": float(np.percentile(angle, 90)), "n": int(len(angle))}


def outliers(rows: list[dict], mids: list[str]) -> dict:
    """Finding g, per matcher and diagnostic it reports: the median and p90 share of points (or correspondences) rejected
    as outliers over its registrations (gicp's inlier_share turned into 1 - inlier_share); {} for a matcher reporting none."""
    out = {}
    for mid in mids:
        c = columns(rows, mid)
        node = {}
        for key in OUTLIER_KEYS:
            v = c[key][np.isfinite(c[key])]
            if not len(v):
                continue
            name, v = ("rejected_share", 1.0 - v) if key == "inlier_share" else (key, v)
            node[name] = {"median": float(np.median(v)), "p90": float(np.percentile(v, 90)), "n": int(len(v))}
        out[mid] = node
    return out


def compose(pieces: list[ChainPiece]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(t, truth, chained poses, ok) over the whole stretch: each piece's odometry continued from where the previous
    piece's ended (consecutive pieces share their boundary scan, kept once)."""
    t: list[np.ndarray] = []
    truth: list[np.ndarray] = []
    pose: list[np.ndarray] = []
    ok: list[np.ndarray] = []
    for i, p in enumerate(pieces):
        poses, skip = p.track.pose, 1 if i else 0
        finite = np.nonzero(np.isfinite(poses[:, 0, 0]))[0]
        if i and len(finite):  # continue from the previous piece's last pose
            poses = pose[-1][-1] @ np.linalg.inv(poses[finite[0]]) @ poses
        t.append(p.t[skip:])
        truth.append(p.truth[skip:])
        pose.append(poses[skip:])
        ok.append(p.track.ok[skip:])
    return np.concatenate(t), np.concatenate(truth), np.concatenate(pose), np.concatenate(ok)


def planar_heading(pose: np.ndarray) -> np.ndarray:
    """Heading (rad) of chained poses (N, 4, 4; NaN where there is none) as a planar filter integrates odometry (see
    fusion.geometry.planar): the first pose's yaw plus each step's yaw about the body's own z axis. The composed pose's
    yaw would fold the chain's tilt into the heading: with no ground in a river scan (the water returns nothing) a
    6-DoF chain drifts in pitch (kiss_icp: -25 deg in 170 s over the basin, 1100-1450 m) and its yaw swings by 100 deg
    and more as the pitch grows, while its heading proper drifted 5 deg."""
    out = np.full(len(pose), np.nan)
    idx = np.flatnonzero(np.isfinite(pose[:, 0, 0]))
    if not len(idx):
        return out
    steps = np.linalg.solve(pose[idx[:-1]], pose[idx[1:]])
    out[idx] = metrics.yaw_of(pose[idx[:1]])[0] + np.concatenate([[0.0], np.cumsum(metrics.yaw_of(steps))])
    return out


def tilt_deg(pose: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """Angle between the chained and the true body z axes, deg (the pitch and roll the chain got wrong)."""
    cos = np.clip(np.einsum("ij,ij->i", pose[:, :3, 2], truth[:, :3, 2]), -1.0, 1.0)
    return np.degrees(np.arccos(cos))


def yaw_drift(mid: str, pieces: list[ChainPiece], compass_t: np.ndarray, compass_error: np.ndarray) -> dict:
    """Finding h: the chained matcher's heading (planar_heading) minus the truth (deg, wrapped) at the stretch's end and
    its largest, the chain's tilt error at the end and its largest, beside the compass's heading error
    (sim.magnetic_compass at its defaults) at the end and its p95."""
    t, truth, pose, ok = compose(pieces)
    err = np.degrees(wrap_angle(planar_heading(pose) - metrics.yaw_of(truth)))
    finite = np.isfinite(err)
    tilt = tilt_deg(pose[finite], truth[finite])
    comp = np.degrees(np.abs(compass_error))
    return {
        "matcher": mid,
        "scans": int(len(t)),
        "pieces": len(pieces),
        "success": float(ok[1:].mean()) if len(ok) > 1 else math.nan,
        "seconds": float(t[-1] - t[0]) if len(t) else math.nan,
        "distance_m": float(metrics.travelled(truth)[-1]) if len(t) else math.nan,
        "drift_end_deg": float(err[finite][-1]) if finite.any() else math.nan,
        "drift_max_deg": float(np.max(np.abs(err[finite]))) if finite.any() else math.nan,
        "tilt_end_deg": float(tilt[-1]) if len(tilt) else math.nan,
        "tilt_max_deg": float(np.max(tilt)) if len(tilt) else math.nan,
        "compass_end_deg": float(comp[-1]) if len(comp) else math.nan,
        "compass_p95_deg": float(np.percentile(comp, 95)) if len(comp) else math.nan,
        "series": {"t": t[:: max(1, len(t) // 2000)].tolist(), "yaw_error_deg": err[:: max(1, len(t) // 2000)].tolist()},
        "compass_series": {"t": compass_t.tolist(), "error_deg": np.degrees(compass_error).tolist()},
    }
