"""Single-epoch GNSS position: iterative weighted least squares for position and clock, and DOPs."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MAX_ITERATIONS = 10
CONVERGED_M = 1e-6
"""Stop when the remaining linearisation error is below this, metres. A Gauss-Newton step of
length s about a point r from the nearest satellite leaves an error of order s^2 / r, so from a
start within ~100 m of the answer one step is exact to far below a millimetre."""


@dataclass(frozen=True)
class Solution:
    """Position (ENU, m), receiver clock bias (m), unweighted cofactor Q (4x4, for DOP) and the
    weighted position covariance (3x3, m^2) at the solution."""

    enu: np.ndarray
    clock_m: float
    q: np.ndarray
    cov: np.ndarray
    iterations: int

    @property
    def hdop(self) -> float:
        return float(np.sqrt(self.q[0, 0] + self.q[1, 1]))

    @property
    def vdop(self) -> float:
        return float(np.sqrt(self.q[2, 2]))

    @property
    def pdop(self) -> float:
        return float(np.sqrt(self.q[0, 0] + self.q[1, 1] + self.q[2, 2]))


def design(sat_enu: np.ndarray, receiver: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Geometry matrix rows [-u_i, 1] (u_i unit vector receiver -> satellite i) and the ranges."""
    diff = sat_enu - receiver
    rng = np.sqrt(np.einsum("ij,ij->i", diff, diff))
    h = np.empty((len(sat_enu), 4))
    h[:, :3] = -diff / rng[:, None]
    h[:, 3] = 1.0
    return h, rng


def dop(unit_vectors: np.ndarray) -> np.ndarray:
    """Cofactor matrix Q = (H^T H)^-1 for satellites in unit directions (N, 3) in ENU."""
    h = np.hstack([-np.asarray(unit_vectors, dtype=float), np.ones((len(unit_vectors), 1))])
    return np.linalg.inv(h.T @ h)


def solve(sat_enu: np.ndarray, pseudorange: np.ndarray, sigma: np.ndarray, start: np.ndarray) -> Solution:
    """Gauss-Newton WLS for (e, n, u, clock) from >= 4 pseudoranges with one-sigma `sigma` each.

    `start` is (e, n, u, clock) to linearise about (the previous solution, or the world origin).
    Raises ValueError for fewer than 4 satellites or a singular geometry.
    """
    if len(pseudorange) < 4:
        raise ValueError(f"gnss: position needs >= 4 satellites, got {len(pseudorange)}")
    x = np.array(start, dtype=float)
    w = 1.0 / sigma**2
    for iteration in range(1, MAX_ITERATIONS + 1):  # noqa: B007 (the count is returned)
        h, rng = design(sat_enu, x[:3])
        hw = h.T * w
        normal_inv = np.linalg.inv(hw @ h)
        step = normal_inv @ (hw @ (pseudorange - rng - x[3]))
        x += step
        if step[:3] @ step[:3] < CONVERGED_M * rng.min():  # the clock enters linearly
            break
    # The last step was short: the geometry at its start is the solution's to ~1e-8 rad.
    return Solution(enu=x[:3], clock_m=float(x[3]), q=np.linalg.inv(h.T @ h), cov=normal_inv[:3, :3], iterations=iteration)
