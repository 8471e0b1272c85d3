"""IMU batches and compass headings along a tests.fusion_streams trajectory, with a known gyro bias and an optional
compass disturbance (steel) window, merged into its events; and a runner that feeds every kind of event."""

from __future__ import annotations

import math

import numpy as np

from riverbench.rng import stream
from riverbench.samples import HeadingSample, ImuSamples
from tests.fusion_streams import pose_at

GRAVITY = 9.80665


def inertial_events(
    t_grid: np.ndarray,
    poses: np.ndarray,
    duration: float,
    gyro_bias_dps: float = 0.5,
    gyro_noise_dps: float = 0.007,
    imu_hz: float = 100.0,
    batch_s: float = 0.1,
    heading_hz: float = 10.0,
    heading_sigma_deg: float = 1.0,
    disturbance: tuple[float, float, float] | None = None,
    seed: int = 0,
) -> list[tuple]:
    """("imu", stamp, ImuSamples) per batch_s and ("heading", stamp, HeadingSample) at heading_hz; a disturbance
    (start, end, deg) adds a deviation to the compass over [start, end), with the field's intensity raised as steel does."""
    rng = stream(seed, "test.inertial")
    events: list[tuple] = []
    dt = 1.0 / imu_hz
    ts = np.arange(1, int(duration * imu_hz)) * dt
    yaw = np.unwrap(np.array([pose_at(t_grid, poses, t)[2] for t in ts]))
    rate = np.gradient(yaw, ts)
    gyro = np.zeros((len(ts), 3))
    gyro[:, 2] = rate + math.radians(gyro_bias_dps) + math.radians(gyro_noise_dps) * math.sqrt(imu_hz) * rng.standard_normal(len(ts))
    accel = np.tile([0.0, 0.0, GRAVITY], (len(ts), 1))
    per_batch = int(round(batch_s * imu_hz))
    for i in range(0, len(ts), per_batch):
        sl = slice(i, i + per_batch)
        events.append(("imu", float(ts[sl][-1]), ImuSamples(ts[sl], gyro[sl], accel[sl], math.radians(gyro_noise_dps), 60e-6 * GRAVITY)))
    for t in np.arange(1, int(duration * heading_hz)) / heading_hz:
        true = pose_at(t_grid, poses, float(t))[2]
        field = np.array([20.58, 0.0, -47.01])
        measured = true + math.radians(heading_sigma_deg) * rng.standard_normal()
        if disturbance is not None and disturbance[0] <= t < disturbance[1]:
            measured += math.radians(disturbance[2])
            field = field * 1.05
        dip = math.degrees(math.atan2(-field[2], math.hypot(field[0], field[1])))
        events.append(("heading", float(t), HeadingSample(float(t), float(measured), field, math.radians(heading_sigma_deg), dip)))
    return events


def merged(base: list[tuple], extra: list[tuple]) -> list[tuple]:
    """Both event lists in time order (at equal stamps: IMU, heading, then the base's)."""
    order = {"imu": 0, "heading": 1}
    return sorted(base + extra, key=lambda e: (e[1], order.get(e[0], 2)))


def run(estimator, events: list[tuple]) -> dict:
    """Feed every event; after each scan's match: stamp and the estimated (x, y, yaw); and whether each heading was used."""
    out: dict = {"stamp": [], "est": [], "heading_used": []}
    for kind, stamp, payload in events:
        if kind == "imu":
            estimator.add_imu(payload)
            continue
        if kind == "heading":
            out["heading_used"].append((stamp, estimator.add_heading(payload)))
            continue
        if kind == "match":
            estimator.add_match(stamp, payload)
        else:
            estimator.add_fix(payload)
        pose = estimator.pose
        out["stamp"].append(stamp)
        out["est"].append([pose[0, 3], pose[1, 3], math.atan2(pose[1, 0], pose[0, 0])])
    out["stamp"], out["est"] = np.asarray(out["stamp"]), np.asarray(out["est"])
    return out
