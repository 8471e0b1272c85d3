"""The receiver's own navigation filter: constant-velocity Kalman filter on raw position solutions.

Consumer receivers smooth their single-epoch solutions with a low-process-noise kinematic filter,
coast on it (dead reckoning, NMEA quality 6) through short outages, and distrust fixes that jump
away from the prediction (innovations beyond a chi-square gate only enter with an inflated
covariance). After a blackout the coasted state can be wrong and the filter then walks back to
the measurements over several seconds instead of jumping: the smoothed wrong estimate seen in the
field study.
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

_EYE3 = np.eye(3)


class FilterConfig(BaseModel):
    """Receiver navigation filter settings."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    process_noise_h: float = Field(
        0.003, gt=0.0, description="Horizontal acceleration noise density of the CV model, m^2/s^3 (low: trusts its model)."
    )
    process_noise_v: float = Field(0.002, gt=0.0, description="Vertical acceleration noise density, m^2/s^3.")
    initial_speed_sigma: float = Field(3.0, gt=0.0, description="Velocity sigma at (re)initialisation, m/s.")
    fix_sigma_m: float = Field(
        2.5,
        gt=0.0,
        description="Added in quadrature per axis to a raw fix's formal covariance: the filter's allowance for "
        "errors the geometry does not show (slow range errors), m.",
    )
    innovation_gate: float = Field(
        16.27, gt=0.0, description="Chi-square (3 dof, p=0.001) gate; beyond it a fix's covariance is inflated by d2/gate."
    )


class CvKalman:
    """Constant-velocity filter in ENU: state (e, n, u, ve, vn, vu)."""

    def __init__(self, config: FilterConfig):
        self.config = config
        self.x: np.ndarray | None = None
        self.p = np.zeros((6, 6))
        self.t = 0.0
        self._transitions: dict[float, tuple[np.ndarray, np.ndarray]] = {}

    @property
    def initialised(self) -> bool:
        return self.x is not None

    def reset(self) -> None:
        """Forget the state (after an outage longer than the coast limit)."""
        self.x = None

    def predict(self, t: float) -> None:
        """Propagate the state to time t with the CV model."""
        dt = t - self.t
        self.t = t
        if self.x is None or dt <= 0.0:
            return
        f, q = self._transition(dt)
        self.x = f @ self.x
        self.p = f @ self.p @ f.T + q

    def _transition(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """CV transition F and white-acceleration process noise Q over dt (cached: dt repeats)."""
        cached = self._transitions.get(dt)
        if cached is None:
            f = np.eye(6)
            f[:3, 3:] = dt * _EYE3
            q = np.diag([self.config.process_noise_h, self.config.process_noise_h, self.config.process_noise_v])
            cached = f, np.block([[q * dt**3 / 3.0, q * dt**2 / 2.0], [q * dt**2 / 2.0, q * dt]])
            if len(self._transitions) < 64:
                self._transitions[dt] = cached
        return cached

    def update(self, enu: np.ndarray, cov: np.ndarray) -> None:
        """Fuse a raw position fix with covariance cov (3x3); initialise on the first one."""
        r = cov + self.config.fix_sigma_m**2 * _EYE3
        if self.x is None:
            self.x = np.concatenate([enu, np.zeros(3)])
            self.p = np.zeros((6, 6))
            self.p[:3, :3] = r
            self.p[3:, 3:] = self.config.initial_speed_sigma**2 * _EYE3
            return
        y = enu - self.x[:3]
        s_inv = np.linalg.inv(self.p[:3, :3] + r)
        d2 = float(y @ s_inv @ y)
        if d2 > self.config.innovation_gate:
            s_inv = np.linalg.inv(self.p[:3, :3] + r * (d2 / self.config.innovation_gate))
        gain = self.p[:, :3] @ s_inv  # P H^T S^-1
        self.x = self.x + gain @ y
        p = self.p - gain @ self.p[:3, :]
        self.p = 0.5 * (p + p.T)

    @property
    def position(self) -> np.ndarray:
        assert self.x is not None  # asked for only once initialised
        return self.x[:3].copy()

    @property
    def velocity(self) -> np.ndarray:
        assert self.x is not None  # asked for only once initialised
        return self.x[3:].copy()
