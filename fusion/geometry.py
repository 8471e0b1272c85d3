"""Planar (SE(2)) and rigid (SE(3)) helpers: odometry in the lidar frame to base_link planar motion."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from riverbench.angles import wrap_angle


def rot2(yaw: float) -> np.ndarray:
    """2x2 rotation by yaw (counter-clockwise)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s], [s, c]])


def drot2(yaw: float) -> np.ndarray:
    """Derivative of rot2 with respect to yaw."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[-s, -c], [c, -s]])


def skew(v: np.ndarray) -> np.ndarray:
    """3x3 cross-product matrix of v."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def adjoint(T: np.ndarray) -> np.ndarray:
    """6x6 adjoint of a 4x4 rigid transform for twists ordered [translation, rotation]."""
    R, t = T[:3, :3], T[:3, 3]
    ad = np.zeros((6, 6))
    ad[:3, :3] = R
    ad[:3, 3:] = skew(t) @ R
    ad[3:, 3:] = R
    return ad


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of a 4x4 rigid transform."""
    inv = np.eye(4)
    inv[:3, :3] = T[:3, :3].T
    inv[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return inv


def lidar_to_base(T_lidar: np.ndarray, cov_lidar: np.ndarray, mount: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Relative motion and its 6x6 covariance moved from the lidar frame to base_link.

    mount is base_link<-lidar; T_base = mount T_lidar mount^-1 and a perturbation xi of T_lidar
    becomes Ad(mount) xi of T_base, whether applied on the left or the right.
    """
    T_base = mount @ T_lidar @ invert(mount)
    ad = adjoint(mount)
    return T_base, ad @ cov_lidar @ ad.T


def planar(T: np.ndarray, cov6: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(dx, dy, dyaw) of a 4x4 motion and the matching 3x3 block of its [x,y,z,r,p,yaw] covariance."""
    delta = np.array([T[0, 3], T[1, 3], np.arctan2(T[1, 0], T[0, 0])])
    idx = [0, 1, 5]
    return delta, cov6[np.ix_(idx, idx)]


def compose(pose: np.ndarray, delta: np.ndarray) -> np.ndarray:
    """SE(2) pose (x, y, yaw) followed by a body-frame step (dx, dy, dyaw)."""
    xy = pose[:2] + rot2(pose[2]) @ delta[:2]
    return np.array([xy[0], xy[1], float(wrap_angle(pose[2] + delta[2]))])


def between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Body-frame step from SE(2) pose a to pose b (inverse of compose)."""
    d = rot2(a[2]).T @ (b[:2] - a[:2])
    return np.array([d[0], d[1], float(wrap_angle(b[2] - a[2]))])


def pose_matrix(x: float, y: float, z: float, yaw: float) -> np.ndarray:
    """4x4 world<-base_link for a level vessel at (x, y, z) heading yaw."""
    T = np.eye(4)
    T[:2, :2] = rot2(yaw)
    T[:3, 3] = (x, y, z)
    return T


def is_psd(cov: np.ndarray) -> bool:
    """True when cov is finite, symmetric and positive semi-definite (to rounding)."""
    if not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T, rtol=1e-6, atol=1e-12):
        return False
    return bool(np.linalg.eigvalsh(0.5 * (cov + cov.T)).min() >= -1e-9 * max(1.0, np.abs(cov).max()))


def tilt_rate(rotation: np.ndarray, dt: float) -> np.ndarray:
    """The roll and pitch part of the angular velocity (rad/s, body frame, yaw component zero) of a rotation over dt s:
    its rotation vector over dt, whose yaw the planar filters take from the step itself."""
    if not dt > 0.0:
        return np.zeros(3)
    rate = Rotation.from_matrix(rotation).as_rotvec() / dt
    rate[2] = 0.0
    return rate
