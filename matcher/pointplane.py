"""Point-to-plane residuals at a registration's solution: robust Hessian, residual variance, outlier share."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from matcher.motion import gram, transform


@dataclass(frozen=True)
class PlaneFit:
    """Gauss-Newton information of the point-to-plane objective at a pose (left perturbation [dt, dtheta])."""

    H: np.ndarray
    sigma2: float
    fitness: float
    outlier_share: float
    n_correspondences: int


def point_to_plane_fit(
    source: np.ndarray,
    T: np.ndarray,
    target: np.ndarray,
    target_normals: np.ndarray,
    target_tree: cKDTree,
    max_distance_m: float,
    tukey_k_m: float,
    target_weights: np.ndarray | None = None,
) -> PlaneFit:
    """Pair each source point moved by T with its nearest target point within max_distance_m and
    weigh the plane residual with Tukey's biweight (k = tukey_k_m), times the partner's entry in
    target_weights if given (how far its normal can be trusted); residuals beyond k are outliers."""
    q = transform(source, T[:3, :3], T[:3, 3])
    dist, idx = target_tree.query(q, distance_upper_bound=max_distance_m)
    paired = np.isfinite(dist)
    q, idx = q[paired], idx[paired]
    n = target_normals[idx]
    e = np.einsum("ij,ij->i", n, q - target[idx])
    w = np.clip(1.0 - (e / tukey_k_m) ** 2, 0.0, None) ** 2
    if target_weights is not None:
        w = w * target_weights[idx]
    J = np.hstack([n, np.cross(q, n)])
    H = gram(J, w)
    weight = float(w.sum())
    sigma2 = float((w * e**2).sum() / max(weight - 6.0, 1.0))
    m = int(paired.sum())
    return PlaneFit(
        H=H,
        sigma2=sigma2,
        fitness=m / max(len(source), 1),
        outlier_share=float((np.abs(e) >= tukey_k_m).mean()) if m else 1.0,
        n_correspondences=m,
    )
