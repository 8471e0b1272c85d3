"""What an inertial sensor on the vessel feels: body angular velocity and specific force from the exact motion.

The open-loop trajectory is differentiated analytically (station from the speed profile, heading and
its curvature along the route, the waves' sinusoids); a driven trajectory from its integrated state
(body velocities, yaw rate) and the waves; any other pose source by a fourth-order central
difference of its exact pose function. Gravity is the WGS-84 normal gravity at the world's latitude
and the Earth's rotation is sensed by the gyro when asked for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.trajectory import yaw_pitch_roll_matrices
from sim.waves import WaveMotion

EARTH_RATE = 7.292115e-5
"""WGS-84 Earth rotation rate, rad/s (NIMA TR8350.2, Table 3.1)."""
FD_STEP_S = 1e-3
"""Step of the finite difference used for pose sources without their own derivatives."""


def normal_gravity(lat_deg: float) -> float:
    """WGS-84 normal gravity on the ellipsoid at geodetic latitude lat_deg, m/s^2 (Somigliana; NIMA TR8350.2, eq. 4-1)."""
    s2 = math.sin(math.radians(lat_deg)) ** 2
    return 9.7803253359 * (1.0 + 0.00193185265241 * s2) / math.sqrt(1.0 - 0.00669437999013 * s2)


@dataclass(frozen=True)
class BodyMotion:
    """At times ts: rotation world<-body (N, 3, 3), body angular velocity (N, 3) rad/s and body specific force (N, 3) m/s^2."""

    rotation: np.ndarray
    omega: np.ndarray
    specific_force: np.ndarray


def wave_states(waves: WaveMotion, ts: np.ndarray) -> tuple[np.ndarray, ...]:
    """Heave, roll, pitch and their first and second time derivatives at ts (the waves are sums of sinusoids)."""
    arg = np.multiply.outer(ts, waves.omega) + waves.phase
    s, c, w = np.sin(arg), np.cos(arg), waves.omega
    heave, heave_dd = s @ waves.heave_amp, -(s * w**2) @ waves.heave_amp
    roll, roll_d, roll_dd = s @ waves.roll_amp, (c * w) @ waves.roll_amp, -(s * w**2) @ waves.roll_amp
    pitch, pitch_d, pitch_dd = c @ waves.pitch_amp, -(s * w) @ waves.pitch_amp, -(c * w**2) @ waves.pitch_amp
    return heave, heave_dd, roll, roll_d, roll_dd, pitch, pitch_d, pitch_dd


def body_rates(roll: np.ndarray, pitch: np.ndarray, roll_d: np.ndarray, pitch_d: np.ndarray, yaw_d: np.ndarray) -> np.ndarray:
    """Body angular velocity (N, 3) from ZYX Euler angles and their rates (the strapdown kinematic relation)."""
    sr, cr, sp, cp = np.sin(roll), np.cos(roll), np.sin(pitch), np.cos(pitch)
    return np.stack([roll_d - yaw_d * sp, pitch_d * cr + yaw_d * sr * cp, -pitch_d * sr + yaw_d * cr * cp], axis=-1)


def body_motion(trajectory, ts: np.ndarray, gravity: float, earth_rate_enu: np.ndarray, lever: np.ndarray) -> BodyMotion:
    """Angular velocity and specific force of a sensor at `lever` (base_link metres) on the vessel at times ts."""
    ts = np.atleast_1d(np.asarray(ts, dtype=float))
    plane = trajectory.plane_motion(ts) if hasattr(trajectory, "plane_motion") else None
    waves = getattr(trajectory, "waves", None)
    if plane is None or waves is None:
        return _finite_difference(trajectory, ts, gravity, earth_rate_enu, lever)
    heave, heave_dd, roll, roll_d, roll_dd, pitch, pitch_d, pitch_dd = wave_states(waves, ts)
    rotation = yaw_pitch_roll_matrices(plane.yaw, pitch, roll)
    omega = body_rates(roll, pitch, roll_d, pitch_d, plane.yaw_rate)
    accel = np.concatenate([plane.acceleration, heave_dd[:, None]], axis=1)
    if np.any(lever):
        # angular acceleration by a central difference of the (smooth) analytic body rates
        h = FD_STEP_S
        up, down = (_omega_at(trajectory, waves, ts + d) for d in (h, -h))
        alpha = (up - down) / (2.0 * h)
        lever_accel = np.cross(alpha, lever) + np.cross(omega, np.cross(omega, lever))
        accel = accel + np.einsum("nij,nj->ni", rotation, lever_accel)
    return _sensed(rotation, omega, accel, gravity, earth_rate_enu)


def _omega_at(trajectory, waves: WaveMotion, ts: np.ndarray) -> np.ndarray:
    plane = trajectory.plane_motion(ts)
    _, _, roll, roll_d, _, pitch, pitch_d, _ = wave_states(waves, ts)
    return body_rates(roll, pitch, roll_d, pitch_d, plane.yaw_rate)


def _sensed(rotation: np.ndarray, omega: np.ndarray, accel: np.ndarray, gravity: float, earth_rate_enu: np.ndarray) -> BodyMotion:
    """Add the Earth's rate to the body rate and gravity's reaction to the acceleration, both into the body frame."""
    up = accel + np.array([0.0, 0.0, gravity])
    force = np.einsum("nji,nj->ni", rotation, up)
    omega = omega + np.einsum("nji,j->ni", rotation, earth_rate_enu)
    return BodyMotion(rotation, omega, force)


def _finite_difference(trajectory, ts: np.ndarray, gravity: float, earth_rate_enu: np.ndarray, lever: np.ndarray) -> BodyMotion:
    """Fourth-order central differences of the exact pose function (for pose sources without analytic derivatives)."""
    h = FD_STEP_S
    offsets = np.array([-2.0, -1.0, 0.0, 1.0, 2.0]) * h
    poses = trajectory.poses((ts[:, None] + offsets).ravel()).reshape(len(ts), 5, 4, 4)
    sensor = poses[..., :3, 3] + np.einsum("nkij,j->nki", poses[..., :3, :3], lever)
    d1 = np.array([1.0, -8.0, 0.0, 8.0, -1.0]) / (12.0 * h)
    d2 = np.array([-1.0, 16.0, -30.0, 16.0, -1.0]) / (12.0 * h * h)
    accel = np.einsum("k,nki->ni", d2, sensor)
    rotation = poses[:, 2, :3, :3]
    # body rate from the rotation's derivative: skew(omega) = R^T dR/dt
    r_dot = np.einsum("k,nkij->nij", d1, poses[..., :3, :3])
    skew = np.einsum("nji,njk->nik", rotation, r_dot)
    omega = 0.5 * np.stack([skew[:, 2, 1] - skew[:, 1, 2], skew[:, 0, 2] - skew[:, 2, 0], skew[:, 1, 0] - skew[:, 0, 1]], axis=-1)
    return _sensed(rotation, omega, accel, gravity, earth_rate_enu)


def earth_rate_enu(lat_deg: float) -> np.ndarray:
    """The Earth's rotation vector in the local ENU frame at latitude lat_deg, rad/s."""
    lat = math.radians(lat_deg)
    return EARTH_RATE * np.array([0.0, math.cos(lat), math.sin(lat)])
