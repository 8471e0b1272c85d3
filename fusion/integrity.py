"""Horizontal protection level: the radius that bounds a fused estimate's horizontal error at a stated integrity risk.

Rule (the fault-free bound of a Gaussian estimate, as in RTCA DO-229 and Joerger and Pervan 2013, "Kalman filter-based
integrity monitoring against sensor faults", J. Guidance, Control and Dynamics 36(2):349-361): with the filter's 2x2
horizontal covariance P and its largest eigenvalue lambda_max, every error e satisfies |e|^2 / lambda_max <= e' P^-1 e,
and e' P^-1 e is chi-square with 2 degrees of freedom, so

    P(|e| > k sqrt(lambda_max)) <= P(chi2_2 > k^2) = exp(-k^2 / 2) = integrity risk,  k = sqrt(-2 ln(integrity risk)).

HPL = k sqrt(lambda_max) holds exactly as long as the filter's covariance is honest: a fix the monitor let through with
an error its model does not carry (a reflected signal's tens of metres) breaks it, and the bench counts those epochs as
misleading information (error above HPL) and, above the alert limit while HPL was below it, hazardous.
"""

from __future__ import annotations

import math

import numpy as np


def kappa(integrity_risk: float) -> float:
    """The multiplier k of sqrt(lambda_max) whose circle a 2-D Gaussian error leaves with probability integrity_risk."""
    if not 0.0 < integrity_risk < 1.0:
        raise ValueError(f"integrity risk must be in (0, 1), got {integrity_risk}")
    return math.sqrt(-2.0 * math.log(integrity_risk))


def protection_level(cov_xy: np.ndarray, integrity_risk: float) -> float:
    """k sqrt(lambda_max(cov_xy)) in metres; NaN for a covariance that is not finite."""
    cov = np.asarray(cov_xy, dtype=float)
    if cov.shape != (2, 2) or not np.all(np.isfinite(cov)):
        return math.nan
    largest = float(np.linalg.eigvalsh(0.5 * (cov + cov.T))[-1])
    return kappa(integrity_risk) * math.sqrt(max(largest, 0.0))
