"""Covariance from a registration Hessian (sigma^2 H^-1), inflated along degenerate directions."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Degeneracy:
    """Eigen-analysis of the Hessian with rotations scaled to metres at `rotation_scale_m`."""

    eigenvalues: np.ndarray
    eigenvectors: np.ndarray
    degenerate: np.ndarray

    def as_info(self) -> dict:
        return {
            "degenerate": bool(self.degenerate.any()),
            "hessian_eigenvalues": self.eigenvalues.tolist(),
            "degenerate_directions": self.eigenvectors[:, self.degenerate].T.tolist(),
        }


def covariance_from_hessian(
    H: np.ndarray,
    sigma2: float,
    rotation_scale_m: float,
    degenerate_ratio: float,
    degenerate_sigma_m: float,
    is_rotation: tuple[bool, ...] = (False, False, False, True, True, True),
) -> tuple[np.ndarray, Degeneracy]:
    """Covariance of the parameters (default [tx, ty, tz, rx, ry, rz]; `is_rotation` marks angles)
    from the Gauss-Newton Hessian H of the same parameters (residual variance sigma2). Directions
    whose eigenvalue (angles expressed as arc length at rotation_scale_m) is below degenerate_ratio x
    the largest are unconstrained: their standard deviation is raised to at least degenerate_sigma_m
    (rad x rotation_scale_m for angles)."""
    D = np.diag([1.0 / rotation_scale_m if rot else 1.0 for rot in is_rotation])
    n = len(is_rotation)
    Hs = D @ H @ D
    Hs = 0.5 * (Hs + Hs.T)
    lam, V = np.linalg.eigh(Hs)
    top = max(float(lam[-1]), 0.0)
    degenerate = lam <= degenerate_ratio * top if top > 0 else np.ones(n, bool)
    var = np.full(n, degenerate_sigma_m**2)
    positive = lam > 0
    var[positive] = sigma2 / lam[positive]
    var[degenerate] = np.maximum(var[degenerate], degenerate_sigma_m**2)
    cov_s = (V * var) @ V.T
    cov = D @ cov_s @ D
    return 0.5 * (cov + cov.T), Degeneracy(lam, V, degenerate)


def to_xyzrpy(cov_param: np.ndarray, J: np.ndarray) -> np.ndarray:
    """Propagate a parameter covariance to [x, y, z, roll, pitch, yaw] with the 6x6 Jacobian J."""
    cov = J @ cov_param @ J.T
    return 0.5 * (cov + cov.T)


def left_perturbation_jacobian(T: np.ndarray) -> np.ndarray:
    """d[x, y, z, roll, pitch, yaw] / d[dt, dtheta] for T' = Exp([dt, dtheta]) T (small roll/pitch)."""
    J = np.eye(6)
    t = T[:3, 3]
    J[:3, 3:] = -np.array([[0.0, -t[2], t[1]], [t[2], 0.0, -t[0]], [-t[1], t[0], 0.0]])
    return J


def right_perturbation_jacobian(T: np.ndarray) -> np.ndarray:
    """d[x, y, z, roll, pitch, yaw] / d[dt, dtheta] for T' = T Exp([dt, dtheta]) (small roll/pitch)."""
    J = np.zeros((6, 6))
    J[:3, :3] = T[:3, :3]
    J[3:, 3:] = T[:3, :3]
    return J
