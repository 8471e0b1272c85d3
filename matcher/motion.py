"""Rigid-motion helpers: SE(3) exp/log, pose <-> [x, y, z, roll, pitch, yaw], constant-velocity de-skew."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial.transform import Rotation

_SMALL_ANGLE = 1e-9


def skew(w: np.ndarray) -> np.ndarray:
    """3x3 cross-product matrix of a 3-vector."""
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _columns(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The x, y and z columns of (N, 3) points (views)."""
    return points[:, 0], points[:, 1], points[:, 2]


def _rotated_columns(cols: Sequence[np.ndarray], R: np.ndarray) -> list[np.ndarray]:
    """The three columns of points @ R.T from the points' three columns: column k is
    p0 R[k, 0] + p1 R[k, 1] + p2 R[k, 2], added in that order. One (N,) array per column, summed in
    place: broadcasting (N, 1) columns against (3,) rows, three entries per inner loop, takes
    several times longer at a scan's size for the same products and sums."""
    out = []
    for k in range(3):
        col = cols[0] * R[k, 0]
        col += cols[1] * R[k, 1]
        col += cols[2] * R[k, 2]
        out.append(col)
    return out


def transform(points: np.ndarray, R: np.ndarray, t: np.ndarray | None = None) -> np.ndarray:
    """points @ R.T + t for (N, 3) points, without BLAS: its thread pool, woken per call, stalls
    for milliseconds on a busy machine, far longer than these three multiply-adds take. Column by
    column (`_rotated_columns`), the same operations in the same order as
    points[:, 0:1] * R[:, 0] + points[:, 1:2] * R[:, 1] + points[:, 2:3] * R[:, 2] + t."""
    cols = _rotated_columns(_columns(points), R)
    if t is not None:
        for k, col in enumerate(cols):
            col += t[k]
    return np.stack(cols, axis=1)


def gram(J: np.ndarray, w: np.ndarray | None = None) -> np.ndarray:
    """J.T @ diag(w) @ J for a tall (N, k) Jacobian, without BLAS (see `transform`)."""
    Jw = J if w is None else J * w[:, None]
    return np.einsum("ni,nj->ij", Jw, J)


def se3_exp(xi: np.ndarray) -> np.ndarray:
    """4x4 pose of the twist xi = [v (m), w (rad)] integrated over unit time."""
    v, w = np.asarray(xi[:3], float), np.asarray(xi[3:], float)
    theta = float(np.linalg.norm(w))
    K = skew(w)
    if theta < _SMALL_ANGLE:
        R, V = np.eye(3) + K, np.eye(3) + 0.5 * K
    else:
        A = np.sin(theta) / theta
        B = (1.0 - np.cos(theta)) / theta**2
        C = (theta - np.sin(theta)) / theta**3
        R = np.eye(3) + A * K + B * (K @ K)
        V = np.eye(3) + B * K + C * (K @ K)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, V @ v
    return T


def se3_log(T: np.ndarray) -> np.ndarray:
    """Twist [v, w] whose unit-time exponential is the 4x4 pose T."""
    w = Rotation.from_matrix(T[:3, :3]).as_rotvec()
    theta = float(np.linalg.norm(w))
    K = skew(w)
    if theta < _SMALL_ANGLE:
        V_inv = np.eye(3) - 0.5 * K
    else:
        half = 0.5 * theta
        V_inv = np.eye(3) - 0.5 * K + (1.0 - half / np.tan(half)) / theta**2 * (K @ K)
    return np.concatenate([V_inv @ T[:3, 3], w])


def adjoint(T: np.ndarray) -> np.ndarray:
    """6x6 adjoint of the 4x4 pose T on twists [v, w]: T Exp(xi) T^-1 = Exp(adjoint(T) @ xi)."""
    R, t = T[:3, :3], T[:3, 3]
    A = np.zeros((6, 6))
    A[:3, :3] = A[3:, 3:] = R
    A[:3, 3:] = skew(t) @ R
    return A


def pose_to_xyzrpy(T: np.ndarray) -> np.ndarray:
    """[x, y, z, roll, pitch, yaw] of a 4x4 pose (R = Rz(yaw) Ry(pitch) Rx(roll), as in ROS)."""
    yaw, pitch, roll = Rotation.from_matrix(T[:3, :3]).as_euler("ZYX")
    return np.array([*T[:3, 3], roll, pitch, yaw])


def xyzrpy_to_pose(p: np.ndarray) -> np.ndarray:
    """4x4 pose of [x, y, z, roll, pitch, yaw]."""
    T = np.eye(4)
    T[:3, :3] = Rotation.from_euler("ZYX", [p[5], p[4], p[3]]).as_matrix()
    T[:3, 3] = p[:3]
    return T


def planar(T: np.ndarray) -> np.ndarray:
    """T with z, roll and pitch set to zero (keeps x, y, yaw): a boat's motion prior."""
    p = pose_to_xyzrpy(T)
    p[2:5] = 0.0
    return xyzrpy_to_pose(p)


def deskew(xyz: np.ndarray, t: np.ndarray, twist_per_s: np.ndarray | None) -> np.ndarray:
    """Points measured in the sensor frame at their times t (s after the stamp), moved into the
    frame at the stamp under constant body velocity `twist_per_s` = [v, w] (None: unchanged)."""
    if twist_per_s is None or len(xyz) == 0:
        return xyz
    v, w = np.asarray(twist_per_s[:3], float), np.asarray(twist_per_s[3:], float)
    rate = float(np.linalg.norm(w))
    t = np.asarray(t, float)
    if rate < _SMALL_ANGLE:
        return xyz + np.cross(w, xyz) * t[:, None] + v * t[:, None]
    K = skew(w / rate)
    theta = rate * t
    s, c = np.sin(theta), 1.0 - np.cos(theta)
    p = _columns(xyz)
    Kp = _rotated_columns(p, K)
    KKp = _rotated_columns(Kp, K)
    Kv, KKv = K @ v, K @ K @ v
    c_rate, t_s = c / rate, t - s / rate
    out = []
    for k in range(3):  # (p + s Kp + c KKp) + (t v + (c / rate) Kv + (t - s / rate) KKv), in that order
        rotated = p[k] + s * Kp[k]
        rotated += c * KKp[k]
        translation = t * v[k]
        translation += c_rate * Kv[k]
        translation += t_s * KKv[k]
        rotated += translation
        out.append(rotated)
    return np.stack(out, axis=1)


def deskew_planar(xy: np.ndarray, t: np.ndarray, twist_per_s: np.ndarray | None) -> np.ndarray:
    """`deskew` of x, y only, for a planar twist (vx, vy, yaw rate; the rest is ignored)."""
    if twist_per_s is None or len(xy) == 0:
        return xy
    vx, vy, wz = float(twist_per_s[0]), float(twist_per_s[1]), float(twist_per_s[5])
    if abs(wz) < _SMALL_ANGLE:
        return xy + np.stack([vx * t, vy * t], axis=1)
    theta = wz * t
    s, c = np.sin(theta), np.cos(theta)
    a, b = s / wz, (1.0 - c) / wz  # integral of the rotating body velocity
    x = c * xy[:, 0] - s * xy[:, 1] + a * vx - b * vy
    y = s * xy[:, 0] + c * xy[:, 1] + b * vx + a * vy
    return np.stack([x, y], axis=1)


def twist_changed(a: np.ndarray | None, b: np.ndarray | None, dt: float, tol_m: float = 0.01, tol_rad: float = 1e-3) -> bool:
    """Whether two twists differ by more than tol_m / tol_rad over dt (a de-skew worth redoing)."""
    if a is None or b is None:
        return a is not b
    d = np.abs((np.asarray(a) - np.asarray(b)) * dt)
    return bool(d[:3].max() > tol_m or d[3:].max() > tol_rad)


SPEED_WALK_MPS_PER_SQRT_S = 0.3
"""How far a vessel's velocity may wander where the scans stop measuring it, m/s per sqrt(s): a velocity random walk
whose 3 sigma after 10 s is 3 m/s, a small craft's full range (the WAM-V 16's 500 N on 190 kg accelerate it at up to
2.6 m/s^2; under way the library's vessels change speed by 0.03 m/s^2)."""


class ConstantVelocity:
    """Body twist per second from the last good relative motion; predicts the next one. Beside it, how well the
    translation velocity is known: each match's covariance fused with what was known before, grown by the speed's
    random walk (SPEED_WALK_MPS_PER_SQRT_S), so a direction a degenerate match left unmeasured (its prior kept, its
    variance "unknown") stays as well known as the last match that measured it, less the walk since."""

    def __init__(self) -> None:
        self.twist_per_s: np.ndarray | None = None
        self.velocity_cov: np.ndarray | None = None  # 3x3 covariance of the translation velocity, (m/s)^2

    def predict(self, dt: float) -> np.ndarray:
        """Relative pose over dt seconds (identity when there is no estimate)."""
        if self.twist_per_s is None:
            return np.eye(4)
        return se3_exp(self.twist_per_s * dt)

    def translation_cov(self, dt: float) -> np.ndarray | None:
        """3x3 covariance of the predicted translation over dt seconds (None when no motion with a covariance is known)."""
        if self.velocity_cov is None:
            return None
        return (self.velocity_cov + np.eye(3) * SPEED_WALK_MPS_PER_SQRT_S**2 * dt) * dt**2

    def update(self, T: np.ndarray, dt: float, cov: np.ndarray | None = None) -> None:
        """Take the motion T over dt seconds (and its 6x6 [x, y, z, roll, pitch, yaw] covariance, when known)."""
        self.twist_per_s = se3_log(T) / dt
        measured = None if cov is None else np.asarray(cov, dtype=float)[:3, :3] / dt**2
        if measured is None or not np.isfinite(measured).all() or np.linalg.eigvalsh(0.5 * (measured + measured.T))[0] <= 0.0:
            self.velocity_cov = None  # no usable covariance (a plugin's may be anything): the velocity's is unknown
            return
        if self.velocity_cov is None:
            self.velocity_cov = measured
            return
        before = self.velocity_cov + np.eye(3) * SPEED_WALK_MPS_PER_SQRT_S**2 * dt
        self.velocity_cov = np.linalg.inv(np.linalg.inv(before) + np.linalg.inv(measured))

    def reset(self) -> None:
        self.twist_per_s = None
        self.velocity_cov = None
