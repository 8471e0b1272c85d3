"""ekf: extended Kalman filter on (x, y, yaw, body velocities, GPS bias) with a stochastic clone for
odometry.

A match is a relative measurement between the pose at the matcher's reference scan (a cloned copy
of the state kept since then) and the pose now, with the matcher's full covariance rotated into
the state by the Jacobian: an along-canal variance leaves that direction to GPS. Between matches,
and when the matcher fails, the pose follows a constant-velocity model whose covariance grows.
The receiver's error is time-correlated (its own filter, slowly changing multipath): it is a
first-order Gauss-Markov bias state with the receiver's HDOP-scaled variance and time constant
gps_correlation_s, plus a small white part; with gps_correlation_s = 0 fixes are independent.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from pydantic import Field
from scipy.stats import chi2

from fusion.bootstrap import Alignment
from fusion.estimator import Estimator
from fusion.geometry import between, compose, drot2, rot2
from fusion.monitors import Monitor
from fusion.observation import POSITION_QUALITIES, FixObservation
from fusion.params import MotionModelParams
from riverbench.angles import wrap_angle

X, Y, TH, V, VL, W, BX, BY, CX, CY, CTH, BG = range(12)
POSE, VEL, BIAS, CLONE = slice(0, 3), slice(3, 6), slice(6, 8), slice(8, 11)
"""With an IMU the state has a 12th entry, BG, the yaw-rate bias of the gyro; without, the 11 of the original filter."""


class EkfParams(MotionModelParams):
    """EKF parameters on top of the shared motion and GPS model (see MotionModelParams)."""

    monitor: str = Field(
        "combined_cn0", description="GPS integrity monitor [combined_cn0 (consistency + cn0), the best measured by benchmarks/monitors.py]"
    )
    position_walk_sigma: float = Field(0.02, ge=0, description="extra position random walk, m/sqrt(s) [0.02]")
    odom_gate_prob: float = Field(
        0.999999,
        gt=0.5,
        lt=1.0,
        description="chi-square (3 dof) gate on a match's innovation; a match beyond it is refused as a matcher failure [0.999999, gate at 30.7]",
    )
    sway_time_constant_s: float | None = Field(
        5.0,
        gt=0,
        description="the sideways body velocity decays towards zero with this time constant, s: a hull's sway is damped "
        "(the VRX WAM-V 16 model, sim.dynamics: (180 + 18) kg / 40 N s/m = 5 s), so without a measurement of it (no "
        "match, or one that leaves it free) the filter does not let it drift, and with the receiver's velocity over "
        "ground, which fixes only the sum of the heading's and the sideslip's shares across the track, it is the "
        "heading that takes the difference [5.0; None: a random walk, as before the receiver's velocity was fused]",
    )
    gps_velocity_sigma_mps: float | None = Field(
        0.06,
        gt=0,
        description="per-axis sigma of the receiver's velocity over ground (RMC speed and course: Doppler, sim.doppler) at "
        "HDOP 1, m/s; scaled by the fix's HDOP, as the range rates map through the same geometry as the ranges [0.06: "
        "0.05 m/s at the median, the u-blox NEO-M8N and ZED-F9P data sheets' velocity accuracy, at the library's median "
        "HDOP of about 0.7 is 0.042 per axis. None: the velocity is not used]",
    )
    gps_velocity_max_hdop: float = Field(
        2.5,
        gt=0,
        description="a fix with a larger HDOP gives no velocity [2.5: the bound the start-up alignment takes a heading from "
        "the receiver's track under, init_max_hdop]: there the satellites left are few, low and on one side, some "
        "reflected, and their paths' rates are no noise that HDOP scales (quickstart, the Museum of Science deck's edge: "
        "4.3 m/s reported for 1.6 at HDOP 15, inside a gate widened by that HDOP)",
    )
    gps_velocity_gate_prob: float = Field(
        0.999,
        gt=0.5,
        lt=1.0,
        description="chi-square (2 dof) gate on the velocity's innovation; a velocity beyond it is not used [0.999, gate at 13.8]",
    )
    gps_velocity_window: int | None = Field(
        25,
        ge=2,
        description="accepted velocities over which the velocity noise is estimated from its innovations (innovation-based "
        "adaptive estimation, Mohamed and Schwarz 1999, J. Geodesy 73:193-203): the noise used is the larger of the "
        "nominal and the window's innovation covariance less the filter's own share, so the antenna's sway on its mast in "
        "waves (rough_water, sea state 3: 0.17 m/s at the median), which a planar filter does not model, widens it [25: "
        "5 s of fixes at 5 Hz, a few wave periods]",
    )


class Ekf(Estimator):
    """EKF over [x, y, yaw, v_forward, v_left, yaw_rate, bias_e, bias_n, clone_x, clone_y, clone_yaw] (+ gyro bias with an IMU).

    With an IMU the yaw is propagated by the gyro's integral less the bias state, its variance grows with the gyro's
    white noise and the bias's random walk; yaw_rate is then the latest bias-corrected gyro rate (reported, not
    propagated). Compass headings update the yaw directly (Estimator.add_heading gates them)."""

    name = "ekf"
    takes_inertial = True

    def __init__(self, params: EkfParams, monitor: Monitor) -> None:
        super().__init__(params, monitor)
        self.params: EkfParams = params
        self.n = N = 12 if self.uses_imu else 11
        self.x = np.zeros(N)
        self.P = np.eye(N)
        self._bias_var = 0.0  # per-axis variance of the receiver's correlated error (from HDOP)
        self._init = False
        self._odom_gate = float(chi2.ppf(params.odom_gate_prob, 3))
        self._bg: tuple[float, float] | None = None  # the gyro bias and its variance kept across a restart
        self._velocity_gate = float(chi2.ppf(params.gps_velocity_gate_prob, 2))
        self._velocity_excess: deque[np.ndarray] = deque(maxlen=params.gps_velocity_window or 1)  # innovation outer products less H P H^T

    @property
    def initialized(self) -> bool:
        return self._init

    def _initialise(self, alignment: Alignment) -> None:
        N = self.n
        if self.uses_imu and self._init:  # a re-alignment keeps what the filter learnt of the gyro's bias
            self._bg = (float(self.x[BG]), float(self.P[BG, BG]))
        self.x[:] = 0.0
        self.x[POSE] = alignment.pose
        self.P = np.zeros((N, N))
        self.P[POSE, POSE] = alignment.cov
        self.P[V, V] = self.P[VL, VL] = 1.0
        self.P[W, W] = math.radians(10.0) ** 2
        now = self.odometry.pose_at(alignment.stamp)
        velocity = self.odometry.velocity()
        if velocity is not None:  # the last step's rate; as uncertain as the step says, within bounds
            self.x[V : W + 1] = velocity[0]
            self.P[V : W + 1, V : W + 1] = np.diag(np.clip(np.diag(velocity[1]), [0.25, 0.25, 1e-4], [9.0, 9.0, 0.1]))
        ground = alignment.start_velocity(velocity, self.params.init_velocity_sigma_mps)
        if ground is not None:  # the receiver's velocity where the odometry did not see the motion
            self.x[V : VL + 1] = ground[0]
            self.P[V : VL + 1, V : VL + 1] = np.diag(np.clip(np.diag(ground[1]), 0.25, 9.0))
        if self.params.sway_time_constant_s is not None:  # the hull's sway prior: zero, as uncertain as its steady state
            steady = self.params.lateral_accel_sigma**2 * self.params.sway_time_constant_s / 2.0
            info = np.linalg.inv(self.P[V : VL + 1, V : VL + 1])
            info[1, 1] += 1.0 / steady
            cov = np.linalg.inv(info)
            self.x[V : VL + 1] = cov @ (info - np.diag([0.0, 1.0 / steady])) @ self.x[V : VL + 1]
            self.P[V : VL + 1, V : VL + 1] = cov
        clone = alignment.pose
        last_pose = self.odometry.last_pose
        if now is not None and last_pose is not None and self.odometry.last_stamp == self._ref_stamp:
            clone = compose(alignment.pose, between(now, last_pose))
        self.x[CLONE] = clone
        self.P[CLONE, CLONE] = alignment.cov
        self.P[CLONE, POSE] = self.P[POSE, CLONE] = alignment.cov
        self.P[BIAS, BIAS] = np.eye(2) * self._bias_var
        if self.uses_imu:
            self.x[BG], self.P[BG, BG] = self._bg if self._bg is not None else (0.0, math.radians(self.inertial.gyro_bias_sigma_dps) ** 2)
        self._init = True

    def _start_gyro(self) -> None:
        if self._init:  # yaw rate no longer propagates the yaw: cut its ties to the rest
            self.P[W, :] = 0.0
            self.P[:, W] = 0.0
            self.P[W, W] = math.radians(10.0) ** 2

    def _predict(self, stamp: float, yaw_step: float | None = None) -> None:
        dt = stamp - self.stamp
        if dt <= 0.0:
            return
        N = self.n
        p = self.params
        th, v, vl = self.x[TH], self.x[V], self.x[VL]
        c, s = math.cos(th), math.sin(th)
        F = np.eye(N)
        F[X, TH], F[X, V], F[X, VL] = (-v * s - vl * c) * dt, c * dt, -s * dt
        F[Y, TH], F[Y, V], F[Y, VL] = (v * c - vl * s) * dt, s * dt, c * dt
        self.x[X] += (v * c - vl * s) * dt
        self.x[Y] += (v * s + vl * c) * dt
        gyro = self._gyro_rate is not None and self.uses_imu
        if gyro:
            assert self._gyro_rate is not None
            step = self._gyro_rate * dt if yaw_step is None else yaw_step
            self.x[TH] = wrap_angle(th + step - self.x[BG] * dt)
            self.x[W] = self._gyro_rate - self.x[BG]
            F[TH, BG] = -dt
        else:
            F[TH, W] = dt
            self.x[TH] = wrap_angle(th + self.x[W] * dt)
        if p.sway_time_constant_s is not None:
            decay = math.exp(-dt / p.sway_time_constant_s)
            self.x[VL] *= decay
            F[VL, VL] = decay
        Q = np.zeros((N, N))
        q_acc = np.array([p.accel_sigma**2, p.lateral_accel_sigma**2, math.radians(p.yaw_accel_sigma_deg) ** 2])
        # white acceleration integrated over dt: velocity dt, position-velocity dt^2/2, position dt^3/3
        G = np.zeros((3, 3))
        G[:2, :2] = rot2(th)
        G[2, 2] = 1.0
        Qvv = np.diag(q_acc) * dt
        Qpv = G @ np.diag(q_acc) * dt**2 / 2.0
        Qpp = G @ np.diag(q_acc) @ G.T * dt**3 / 3.0
        Q[POSE, POSE] = Qpp + np.diag([p.position_walk_sigma**2 * dt] * 2 + [0.0])
        Q[POSE, 3:6] = Qpv
        Q[3:6, POSE] = Qpv.T
        Q[3:6, 3:6] = Qvv
        if gyro:
            Q[TH, TH] += self._gyro_noise**2 * dt
            Q[BG, BG] = (math.radians(self.inertial.gyro_bias_walk_dph) / 3600.0 / 60.0) ** 2 * dt
        if p.gps_correlation_s > 0:
            rho = math.exp(-dt / p.gps_correlation_s)
            F[BX, BX] = F[BY, BY] = rho
            self.x[BIAS] *= rho
            Q[BIAS, BIAS] = np.eye(2) * self._bias_var * (1.0 - rho**2)
        self.P = F @ self.P @ F.T + Q

    def _update(self, y: np.ndarray, H: np.ndarray, R: np.ndarray, considered: tuple[int, ...] = ()) -> None:
        """Kalman update (Joseph form); the `considered` states keep their values (their gain rows are zero: a Schmidt
        'consider' update, Schmidt 1966), their covariance with the rest still updated consistently."""
        S = H @ self.P @ H.T + R
        K = np.linalg.solve(S, H @ self.P).T
        K[list(considered)] = 0.0
        self.x += K @ y
        self.x[TH] = wrap_angle(self.x[TH])
        self.x[CTH] = wrap_angle(self.x[CTH])
        A = np.eye(self.n) - K @ H
        self.P = A @ self.P @ A.T + K @ R @ K.T
        self.P = 0.5 * (self.P + self.P.T)

    def _odometry(self, stamp: float, step: np.ndarray, step_cov: np.ndarray) -> str:
        if not self._init:
            return ""
        cth = self.x[CTH]
        r_t = rot2(cth).T
        d = self.x[X : Y + 1] - self.x[CX : CY + 1]
        h = np.r_[r_t @ d, wrap_angle(self.x[TH] - cth)]
        H = np.zeros((3, self.n))
        H[:2, X : Y + 1] = r_t
        H[:2, CX : CY + 1] = -r_t
        H[:2, CTH] = drot2(cth).T @ d
        H[2, TH], H[2, CTH] = 1.0, -1.0
        y = step - h
        y[2] = wrap_angle(y[2])
        S = H @ self.P @ H.T + step_cov
        nis = float(y @ np.linalg.solve(S, y))
        if nis > self._odom_gate:
            return f"odometry rejected: innovation {nis:.1f} > gate {self._odom_gate:.1f}"
        self._update(y, H, step_cov)
        self._reanchor(stamp)
        return ""

    def _reanchor(self, stamp: float) -> None:
        if not self._init:
            return
        A = np.eye(self.n)
        A[CLONE, :] = 0.0
        A[CLONE, POSE] = np.eye(3)
        self.x = A @ self.x
        self.P = A @ self.P @ A.T

    def _correlated(self) -> bool:
        return self.params.gps_correlation_s > 0

    def _gps_model(self, obs: FixObservation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Predicted antenna fix, its Jacobian and the measurement noise for this fix."""
        th = self.x[TH]
        h = self.x[X : Y + 1] + rot2(th) @ self.lever
        H = np.zeros((2, self.n))
        H[:, X : Y + 1] = np.eye(2)
        H[:, TH] = drot2(th) @ self.lever
        allowance = np.eye(2) * obs.allowance_m**2  # what a monitor could not rule out (fusion.Verdict.allowance_m)
        if not self._correlated():
            return h, H, obs.cov + allowance
        h = h + self.x[BIAS]
        H[:, BIAS] = np.eye(2)
        return h, H, np.eye(2) * self.params.gps_white_sigma_m**2 + allowance

    def _observe_fix(self, obs: FixObservation) -> None:
        """The receiver's error variance follows its HDOP: the bias is rescaled to it (see _set_bias_level)."""
        var = self.params.bias_variance(float(np.trace(obs.cov)) / 2.0)
        if self._correlated() and self._init and self._bias_var == 0.0:
            self.P[BIAS, BIAS] = np.eye(2) * var  # initialised before any fix: as uncertain as the receiver
            self._bias_var = var
        self._set_bias_level(var)

    def _observe_outage(self) -> None:
        """Through an outage the bias's level is the receiver's error at HDOP 1, not that of the
        last fix (often a high-HDOP one at a deck's edge: HDOP 10 before charles_river's 2463 s
        outage grew the bias sd to 17 m, which then soaked up the dead-reckoning drift)."""
        self._set_bias_level(min(self._bias_var, self.params.bias_variance(self.params.uere_m**2 / 2.0)))

    def _set_bias_level(self, var: float) -> None:
        """The receiver's position error is its range errors mapped through the satellite geometry: the range errors
        change slowly (the Gauss-Markov bias, time constant gps_correlation_s), the geometry at once, so a change of
        HDOP scales the bias, its estimate and its covariance, by the ratio of the error levels (position error =
        DOP x UERE; Misra and Enge, Global Positioning System, 2nd ed., section 6.1). Kept at its old level, a bias
        grown at a deck's edge (HDOP 15, sd 8 m) still took most of the first good fix's disagreement after the
        blackout (quickstart fast, seed 0, 2019.1 s: 2.8 m of a 4.6 m innovation), and the position stayed off."""
        if self._correlated() and self._init and self._bias_var > 0.0 and var != self._bias_var:
            k = math.sqrt(var / self._bias_var)
            self.x[BIAS] *= k
            self.P[BIAS, :] *= k
            self.P[:, BIAS] *= k
        self._bias_var = var

    def _update_fix(self, obs: FixObservation) -> None:
        h, H, R = self._gps_model(obs)
        self._update(obs.xy - h, H, R)

    def _predicted_antenna(self, obs: FixObservation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        h, H, R = self._gps_model(obs)
        return h, H @ self.P @ H.T, R

    def _use_velocity(self, obs: FixObservation) -> str:
        """Update with the receiver's velocity over ground: the antenna's, R(yaw) (v + yaw rate x lever), which makes the
        heading observable wherever the boat moves, and the speed along a quay or a deck the matcher leaves free. A
        Doppler velocity carries none of the code's errors that make a fix refused (a reflection's extra path moves the
        range, and the velocity only by how fast that path changes), but a reflected satellite's path does change, so
        only a fix the monitor trusts gives its velocity, which its own innovation gate then judges. The yaw rate is
        considered, not updated (a Schmidt update): the odometry or the gyro measures turns; the course's noise of a few
        degrees a fix, taken into the rate, would turn the heading between fixes (bu_truss_bridge at start-up: the yaw
        rate, 18 deg/s uncertain, jumped 7 deg/s on one fix). Returns why it was not used ('' when it was)."""
        ground = obs.ground_velocity
        sigma = self.params.gps_velocity_sigma_mps
        if sigma is None or ground is None or obs.quality not in POSITION_QUALITIES or not self._init:
            return "no velocity"
        if obs.hdop > self.params.gps_velocity_max_hdop:
            return f"velocity not used: HDOP {obs.hdop:.1f} > {self.params.gps_velocity_max_hdop:g}"
        th, lx, ly = self.x[TH], self.lever[0], self.lever[1]
        body = np.array([self.x[V] - self.x[W] * ly, self.x[VL] + self.x[W] * lx])
        r = rot2(th)
        H = np.zeros((2, self.n))
        H[:, TH] = drot2(th) @ body
        H[:, V], H[:, VL] = r[:, 0], r[:, 1]
        if not self.uses_imu:  # with an IMU the yaw rate is the gyro's, reported, not a state the update may move
            H[:, W] = r @ np.array([-ly, lx])
        y = ground - r @ (body + self._antenna_sway(obs.stamp))
        own = H @ self.P @ H.T
        nominal = np.eye(2) * (sigma * obs.hdop) ** 2
        adaptive = self.params.gps_velocity_window is not None and len(self._velocity_excess) >= 2
        excess = np.mean(self._velocity_excess, axis=0) if adaptive else np.zeros((2, 2))
        R = nominal + _positive_part(excess - nominal)
        nis = float(y @ np.linalg.solve(own + R, y))
        if nis > self._velocity_gate:
            return f"velocity refused: innovation {nis:.1f} > gate {self._velocity_gate:.1f}"
        self._velocity_excess.append(np.outer(y, y) - own)
        self._update(y, H, R, considered=(W,))
        return ""

    def _relock(self, obs: FixObservation) -> None:
        xy = obs.xy - rot2(self.x[TH]) @ self.lever
        shift = xy - self.x[X : Y + 1]
        self.x[X : Y + 1] = xy
        self.x[CX : CY + 1] += shift
        self.x[BIAS] = 0.0
        for block in (slice(X, Y + 1), BIAS, slice(CX, CY + 1)):
            self.P[block, :] = 0.0
            self.P[:, block] = 0.0
        for a in (slice(X, Y + 1), slice(CX, CY + 1)):
            for b in (slice(X, Y + 1), slice(CX, CY + 1)):
                self.P[a, b] = obs.cov
        self.P[BIAS, BIAS] = np.eye(2) * self._bias_var

    def _body_velocity(self) -> np.ndarray:
        return self.x[V : VL + 1].copy()

    def _body_velocity_cov(self) -> np.ndarray:
        return self.P[V : VL + 1, V : VL + 1].copy()

    def _heading(self) -> tuple[float, float]:
        return float(self.x[TH]), float(self.P[TH, TH])

    def _update_heading(self, measured: float, innovation: float, var: float) -> None:
        H = np.zeros((1, self.n))
        H[0, TH] = 1.0
        self._update(np.array([innovation]), H, np.array([[var]]))

    def _restart(self) -> None:
        if self.uses_imu and self._init:
            self._bg = (float(self.x[BG]), float(self.P[BG, BG]))
        self._init = False

    def _pose3(self) -> np.ndarray:
        return self.x[POSE].copy()

    def _cov3(self) -> np.ndarray:
        return self.P[POSE, POSE].copy()


def _positive_part(m: np.ndarray) -> np.ndarray:
    """The symmetric matrix m with its negative eigenvalues set to zero (what of an estimated excess is a variance)."""
    w, v = np.linalg.eigh(0.5 * (m + m.T))
    return (v * np.maximum(w, 0.0)) @ v.T
