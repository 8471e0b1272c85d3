"""Covariance from a registration Hessian (sigma^2 H^-1), inflated along degenerate directions."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field


@dataclass(frozen=True)
class Degeneracy:
    """Eigenvalues (ascending) of the information left on translations and on rotations after
    marginalising the other (Schur complements), and the degenerate directions found."""

    translation_information: np.ndarray
    rotation_information: np.ndarray
    directions: list[np.ndarray]
    direction_information: list[float]  # the marginal information along each of `directions`

    @property
    def translation_ratios(self) -> np.ndarray:
        return _ratios(self.translation_information)

    @property
    def rotation_ratios(self) -> np.ndarray:
        return _ratios(self.rotation_information)

    def as_info(self) -> dict:
        """For MatchResult.info; directions are unit vectors in the matcher's parameter order
        ([tx, ty, tz, rx, ry, rz]; bev3dof: [x, y, yaw]) in the lidar frame."""
        return {
            "degenerate": bool(self.directions),
            "translation_information": self.translation_information.tolist(),
            "rotation_information": self.rotation_information.tolist(),
            "translation_info_ratios": self.translation_ratios.tolist(),
            "rotation_info_ratios": self.rotation_ratios.tolist(),
            "degenerate_directions": [d.tolist() for d in self.directions],
        }


def _ratios(eigenvalues: np.ndarray) -> np.ndarray:
    top = float(eigenvalues[-1]) if len(eigenvalues) else 0.0
    return eigenvalues / top if top > 0 else np.zeros_like(eigenvalues)


def _marginal_information(H: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """Information on the `keep` parameters after marginalising the others (Schur complement)."""
    other = ~keep
    if not other.any():
        return H[np.ix_(keep, keep)]
    A, B, C = H[np.ix_(keep, keep)], H[np.ix_(keep, other)], H[np.ix_(other, other)]
    return A - B @ np.linalg.pinv(C) @ B.T


def covariance_from_hessian(
    H: np.ndarray,
    sigma2: float,
    degenerate_ratio: float,
    degenerate_sigma_m: float,
    degenerate_sigma_rad: float,
    is_rotation: tuple[bool, ...] = (False, False, False, True, True, True),
) -> tuple[np.ndarray, Degeneracy]:
    """Covariance sigma2 H^-1 of the parameters (default [tx, ty, tz, rx, ry, rz]; `is_rotation`
    marks angles) from the Gauss-Newton Hessian H of the same parameters.

    Degeneracy is judged separately for translations and rotations, on the information each keeps
    after marginalising the other: a principal direction whose information is below
    degenerate_ratio x the strongest of its kind is unconstrained (a straight canal leaves motion
    along its walls free), and its standard deviation is raised to at least degenerate_sigma_m
    (translations) or degenerate_sigma_rad (rotations). No variance exceeds those limits either:
    they stand for "unknown" without making the matrix numerically useless."""
    rot = np.asarray(is_rotation, bool)
    limit = np.where(rot, degenerate_sigma_rad, degenerate_sigma_m)
    D = np.diag(limit)  # scale so that every parameter's "unknown" variance is 1
    Hs = D @ (0.5 * (H + H.T)) @ D
    lam, V = np.linalg.eigh(Hs)
    var = np.where(lam > 0, sigma2 / np.where(lam > 0, lam, 1.0), 1.0)
    cov_s = (V * np.minimum(var, 1.0)) @ V.T
    information, directions, along = {}, [], []
    for kind in (False, True):
        keep = rot == kind
        if not keep.any():
            information[kind] = np.zeros(0)
            continue
        info = _marginal_information(H, keep)
        mu, U = np.linalg.eigh(0.5 * (info + info.T))
        information[kind] = mu
        for i in np.flatnonzero(_ratios(mu) < degenerate_ratio) if keep.sum() > 1 else []:
            v = np.zeros(len(rot))
            v[keep] = U[:, i]
            directions.append(v)
            along.append(float(mu[i]))
            vs = v / limit  # the same direction in the scaled parameters
            vs /= np.linalg.norm(vs)
            current = float(vs @ cov_s @ vs)
            cov_s += max(1.0 - current, 0.0) * np.outer(vs, vs)
    cov = D @ cov_s @ D
    return 0.5 * (cov + cov.T), Degeneracy(information[False], information[True], directions, along)


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


class DegeneracyParams(BaseModel):
    """Settings of the covariance's degeneracy handling (matchers with a Hessian)."""

    model_config = ConfigDict(extra="forbid")

    degenerate_ratio: float = Field(
        0.01, gt=0.0, lt=1.0, description="marginal information / strongest of its kind below which a direction is degenerate (default 0.01)"
    )
    degenerate_sigma_m: float = Field(1.0, gt=0.0, description="std. dev. of a degenerate (unknown) translation direction (default 1 m)")
    degenerate_sigma_rad: float = Field(0.1, gt=0.0, description="std. dev. of a degenerate (unknown) rotation direction (default 0.1 rad)")


class FloorParams(BaseModel):
    """Model-error variances added to a 6-DoF sigma^2 H^-1 (which leaves out de-skew error, normal
    errors and correlated noise; measured on charles_river and canal_lock in a light chop)."""

    model_config = ConfigDict(extra="forbid")

    floor_sigma_m: float = Field(0.01, ge=0.0, description="std. dev. added to x, y and z (default 1 cm)")
    floor_sigma_tilt_rad: float = Field(
        0.003, ge=0.0, description="std. dev. added to roll and pitch: waves defeat constant-velocity de-skew (default 3 mrad)"
    )
    floor_sigma_yaw_rad: float = Field(0.0005, ge=0.0, description="std. dev. added to yaw (default 0.5 mrad)")

    def add_to(self, cov: np.ndarray) -> np.ndarray:
        """A 6x6 [x, y, z, roll, pitch, yaw] covariance plus the floor variances."""
        m, t, y = self.floor_sigma_m**2, self.floor_sigma_tilt_rad**2, self.floor_sigma_yaw_rad**2
        return cov + np.diag([m, m, m, t, t, y])
