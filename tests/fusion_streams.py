"""Synthetic streams for the fusion tests: a true planar trajectory, matcher results with known
noise and covariance, and receiver fixes with noise, blackouts, a slowly converging wrong estimate
after a blackout and multipath jumps under low HDOP, each with exact truth."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from fusion.geometry import adjoint, between, invert, rot2
from matcher.result import MatchResult
from riverbench.rng import stream
from sim.gnss_fix import FixTruth, GnssFix

DEFAULT_MOUNT = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 1.8], [0, 0, 0, 1.0]])


@dataclass
class Fault:
    """An extra GPS error over [start, end): a constant offset, or one decaying with time constant tau."""

    start: float
    end: float
    offset: tuple[float, float]
    tau: float | None = None
    blackout: bool = False


@dataclass
class StreamSpec:
    """What to generate: duration, rates, noise, mount, antenna lever and GPS faults."""

    duration: float = 60.0
    speed: float = 2.0
    turn_amp_dps: float = 6.0
    scan_hz: float = 10.0
    fix_hz: float = 5.0
    odom_sigma: tuple[float, float, float] = (0.03, 0.03, math.radians(0.2))
    odom_cov_scale: np.ndarray | None = None  # reported 3x3 body-frame covariance if given
    odom_corrupt: tuple[float, float] = (1.0, 1.0)  # multiply true (dx, dy) before noise
    corrupt_from_s: float = 0.0  # ...in the scans from this time on
    hdop: float = 1.0
    uere: float = 3.0
    gps_noise: bool = True
    gps_tau: float = 30.0  # time constant of the GPS error (first-order Gauss-Markov); 0 = white
    mount: np.ndarray = field(default_factory=lambda: DEFAULT_MOUNT.copy())
    lever: tuple[float, float] = (0.0, 0.0)
    faults: list[Fault] = field(default_factory=list)
    failing_matcher: bool = False
    no_gps: bool = False
    report_velocity: bool = False  # fixes carry the true speed and course over ground (RMC/VTG)
    seed: int = 0


def truth_poses(spec: StreamSpec, dt: float = 0.005) -> tuple[np.ndarray, np.ndarray]:
    """Fine time grid and (N, 3) true base_link poses: gentle speed changes and weaving turns."""
    t = np.arange(0.0, spec.duration + 1.0, dt)
    speed = spec.speed * (1.0 + 0.2 * np.sin(2 * np.pi * t / 40.0))
    yaw_rate = math.radians(spec.turn_amp_dps) * np.sin(2 * np.pi * t / 30.0)
    yaw = 0.5 + np.cumsum(yaw_rate) * dt
    x = np.cumsum(speed * np.cos(yaw)) * dt
    y = np.cumsum(speed * np.sin(yaw)) * dt
    return t, np.column_stack([x, y, yaw])


def pose_at(t_grid: np.ndarray, poses: np.ndarray, t: float) -> np.ndarray:
    i = int(round(t / (t_grid[1] - t_grid[0])))
    return poses[min(i, len(poses) - 1)]


def se3(step: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:2, :2] = rot2(step[2])
    T[:2, 3] = step[:2]
    return T


def generate(spec: StreamSpec) -> tuple[list[tuple], np.ndarray, np.ndarray]:
    """Time-ordered events ("match", stamp, MatchResult) / ("fix", stamp, GnssFix) and the truth grid."""
    t_grid, poses = truth_poses(spec)
    rng_odo, rng_gps = stream(spec.seed, "test.odometry"), stream(spec.seed, "test.gps")
    mount_inv = invert(spec.mount)
    ad = adjoint(mount_inv)
    events: list[tuple] = []
    sigma = np.asarray(spec.odom_sigma)
    reported = spec.odom_cov_scale if spec.odom_cov_scale is not None else np.diag(sigma**2)
    scan_t = np.arange(0.0, spec.duration, 1.0 / spec.scan_hz)
    prev = None
    for ts in scan_t:
        pose = pose_at(t_grid, poses, ts)
        if prev is None:
            result = MatchResult.failure("first scan")
        elif spec.failing_matcher:
            result = MatchResult.failure("always fails")
        else:
            step = between(prev, pose)
            if ts >= spec.corrupt_from_s:
                step[:2] *= spec.odom_corrupt
            step = step + sigma * rng_odo.standard_normal(3)  # noise as odom_sigma, reported as odom_cov_scale
            cov6 = np.diag([1e-4, 1e-4, 1e-4, 1e-6, 1e-6, 1e-6])
            idx = [0, 1, 5]
            cov6[np.ix_(idx, idx)] = reported
            T_lidar = mount_inv @ se3(step) @ spec.mount
            result = MatchResult(T=T_lidar, ok=True, cov=ad @ cov6 @ ad.T, n_points=20000, seconds=0.0)
        events.append(("match", float(ts), result))
        prev = pose
    if not spec.no_gps:
        sigma = spec.uere * spec.hdop / math.sqrt(2.0)
        rho = math.exp(-1.0 / (spec.fix_hz * spec.gps_tau)) if spec.gps_tau > 0 else 0.0
        noise = rng_gps.normal(0.0, sigma, 2)
        for tf in np.arange(0.05, spec.duration, 1.0 / spec.fix_hz):
            events.append(("fix", float(tf), make_fix(spec, t_grid, poses, float(tf), noise if spec.gps_noise else np.zeros(2))))
            noise = rho * noise + math.sqrt(1.0 - rho**2) * rng_gps.normal(0.0, sigma, 2)
    events.sort(key=lambda e: (e[1], e[0] == "fix"))
    return events, t_grid, poses


def make_fix(spec: StreamSpec, t_grid: np.ndarray, poses: np.ndarray, t: float, noise: np.ndarray) -> GnssFix:
    pose = pose_at(t_grid, poses, t)
    antenna = pose[:2] + rot2(pose[2]) @ np.asarray(spec.lever)
    err = noise.copy()
    quality = 1
    for f in spec.faults:
        if f.start <= t < f.end:
            if f.blackout:
                quality = 0
            elif f.tau is None:
                err = err + np.asarray(f.offset)
            else:
                err = err + np.asarray(f.offset) * math.exp(-(t - f.start) / f.tau)
    true_enu = np.array([antenna[0], antenna[1], 1.3])
    enu = np.r_[antenna + err, 1.3] if quality else np.full(3, np.nan)
    ahead = pose_at(t_grid, poses, t + 0.01)
    velocity = (ahead[:2] - pose[:2]) / 0.01  # base_link's, as the lever's share at these turn rates is under 1 cm/s
    reported = spec.report_velocity and quality
    return GnssFix(
        stamp=t,
        lat=0.0,
        lon=0.0,
        alt=0.0,
        enu=enu,
        quality=quality,
        num_sats=8 if quality else 0,
        hdop=spec.hdop if quality else float("nan"),
        vdop=1.5 * spec.hdop,
        pdop=1.8 * spec.hdop,
        truth=FixTruth(enu=true_enu, error=np.r_[err, 0.0] if quality else np.full(3, np.nan)),
        speed_mps=float(np.hypot(*velocity)) if reported else math.nan,
        course_deg=float(np.degrees(np.arctan2(velocity[0], velocity[1])) % 360.0) if reported else math.nan,
    )


def run(estimator, events: list[tuple]) -> dict[str, list]:
    """Feed events; per event: stamp, estimated (x, y, yaw), 3x3 cov, and verdicts per fix."""
    out = {"stamp": [], "est": [], "cov": [], "verdicts": []}
    for kind, stamp, payload in events:
        if kind == "match":
            estimator.add_match(stamp, payload)
        else:
            out["verdicts"].append((stamp, estimator.add_fix(payload), payload))
        pose = estimator.pose
        out["stamp"].append(stamp)
        out["est"].append([pose[0, 3], pose[1, 3], math.atan2(pose[1, 0], pose[0, 0])])
        out["cov"].append(estimator.cov)
    return {k: (np.asarray(v) if k in ("stamp", "est", "cov") else v) for k, v in out.items()}


def errors(out: dict, t_grid: np.ndarray, poses: np.ndarray) -> np.ndarray:
    """(N, 3) estimate - truth at each event (yaw wrapped)."""
    truth = np.array([pose_at(t_grid, poses, t) for t in out["stamp"]])
    err = out["est"] - truth
    err[:, 2] = (err[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return err
