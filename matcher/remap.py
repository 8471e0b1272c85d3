"""Solution remapping: keep the motion prior along the directions a registration left unconstrained.

Along a degenerate direction (a flat deck overhead and walls or piers parallel to the route leave
motion along them free) an ICP's answer is not a measurement: it is wherever its own bias puts it,
and for a LiDAR that is "no motion", since the ring pattern the sensor draws on a flat surface moves
with it. Reporting that as the motion would also de-skew the next scan and seed its match with a
stopped boat. Zhang, Kaess and Singh (ICRA 2016, "On degeneracy of optimization-based state
estimation problems") keep the prior there and the solution elsewhere; this is that, for one
relative pose, on the quadratic model of the registration's cost.
"""

from __future__ import annotations

import numpy as np

from matcher.motion import se3_exp, se3_log


def keep_prior_along(T: np.ndarray, prior: np.ndarray, H: np.ndarray, directions: list[np.ndarray]) -> np.ndarray:
    """T moved so that its left-perturbation offset from `prior` (T = Exp(delta) prior, delta =
    [t, theta]) has no component along any of `directions`, the other components re-minimising the
    quadratic cost with Hessian H (same coordinates) under that constraint. T itself when there are
    no directions."""
    if not directions:
        return T
    delta = se3_log(T @ np.linalg.inv(prior))
    C = np.stack(directions, axis=1)  # (6, k) unit vectors
    Hr = 0.5 * (H + H.T) + 1e-12 * max(float(np.trace(H)), 1.0) * np.eye(6)  # H is singular along the directions
    HiC = np.linalg.solve(Hr, C)
    delta = delta - HiC @ np.linalg.solve(C.T @ HiC, C.T @ delta)
    return se3_exp(delta) @ prior
