"""pf: particle filter with the ekf's inputs and a heavy-tailed (Student-t) GPS likelihood.

Each particle carries a pose, its pose at the matcher's reference scan (clone) and a body
velocity. Between scans particles coast at their velocity with white-acceleration noise. A match
is fused per particle with the optimal Gaussian proposal: the particle's coasted pose (spread by
the process noise since the clone) and the odometry pose (clone + step, with the matcher's full
covariance rotated by the clone's heading) are combined, the particle is drawn from the product,
and weighted by how well the two agreed. So a degenerate odometry direction leaves the particles
to their motion and to GPS there. A fix reweights with a Student-t likelihood, so one wild fix
barely moves the cloud; a receiver's filter smoothing a reflection into a ramp of a metre a second
moves it whole, so the pf runs the ekf's monitor (combined_cn0) and weighs only the fixes it trusts.
With bias_state the receiver's time-correlated error is a Gauss-Markov bias per particle,
Rao-Blackwellised: each particle keeps its bias mean, all share the bias covariance (the same
linear-Gaussian recursion for every one); a particle's bias update is down-weighted like the
Student-t weighs an outlier. Without it (the default) fixes are independent draws; the monitor still
reads the receiver's correlation time, gps_correlation_s.

What the particles cannot carry, the reported covariance does (a Schmidt "consider" covariance, Schmidt 1966; Bierman,
Factorization Methods for Discrete Sequential Estimation, 1977, ch. VIII): fixes weighed as independent draws pull
the cloud onto their common Gauss-Markov error, which averaging them does not remove, so the cloud's spread says
nothing of it. Beside the cloud the filter keeps the variance of the receiver's correlated error its estimate took in
(each fix moves the estimate by the share K the cloud's spread shrank by, as a Kalman gain does: e = (1 - K) e + K b)
and its covariance with the receiver's current error (which decays over gps_correlation_s), and reports the cloud's
spread plus that variance: what the protection level (fusion.integrity) and the exports read. The particles and the
track are unchanged.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from fusion.bootstrap import Alignment
from fusion.estimator import Estimator
from fusion.geometry import between
from fusion.monitors import Monitor
from fusion.observation import FixObservation
from fusion.params import MotionModelParams
from riverbench.angles import wrap_angle
from riverbench.rng import stream


class PfParams(MotionModelParams):
    """PF parameters on top of the shared motion and GPS model: particles, GPS likelihood, resampling, seed."""

    monitor: str = Field(
        "combined_cn0",
        description="GPS integrity monitor [combined_cn0, as the ekf: the Student-t likelihood shrugs off a jump but the "
        "whole cloud follows a receiver's ramp of a metre a second; with it, library [fast] seeds 0-2 canal_multipath pf "
        "APE p95 12.7 -> 2.1 m, gps_jump 6.5 -> 3.8 m, the demo's seed 4 23.3 -> 8.5 m, open water within 0.1 m but "
        "blinding seed 0 0.74 -> 1.34 m (docs/models.md 'Which monitor the pf runs'); none: no hard gate]",
    )
    lateral_accel_sigma: float = Field(
        0.2,
        gt=0,
        description="white-noise acceleration density of the sideways body velocity, m/s^2/sqrt(Hz) [0.2, not the "
        "ekf's 0.05: particles need the wider process noise to stay diverse (with the ekf's earlier 0.1 and 0.05 the "
        "pf's median error over charles_river's first 700 s rose from 3.1 to 4.4 m)]",
    )
    gps_correlation_s: float = Field(
        30.0,
        ge=0,
        description="time constant of the receiver's position error (see EstimatorParams): what the monitor's displacement "
        "tests expect of consecutive fixes, a property of the receiver whatever the pf's likelihood; the particles carry "
        "it as a bias only with bias_state [30 s, as the ekf: at 0 the consistency monitor took two fixes 2 s apart as "
        "independent, its window gate 3.9 times wider, and passed a receiver's walk-back of 1.6 m/s 27.7 m off (the demo, "
        "seed 4, 1774.9 s)]",
    )
    bias_state: bool = Field(
        False,
        description="carry the receiver's correlated error as a per-particle Gauss-Markov bias with time constant "
        "gps_correlation_s [False: fixes are independent Student-t draws; with the bias each particle absorbs its own "
        "offset into its bias and the cloud drifts off, p95 8.9 m against 4.0 m over charles_river's first 700 s]",
    )
    n_particles: int = Field(500, ge=10, description="number of particles [500]")
    gps_dof: float = Field(3.0, gt=0, description="Student-t degrees of freedom of the GPS likelihood [3]")
    resample_ess: float = Field(
        0.5,
        gt=0,
        le=1,
        description="resample when the effective sample size falls below this share of n_particles [0.5]; resampling "
        "is regularised (Liu-West shrinkage and a kernel shaped like the posterior, optimal bandwidth) plus a floor "
        "roughen_m / roughen_deg",
    )
    roughen_m: float = Field(0.02, ge=0, description="floor of the resampling kernel's position spread, m [0.02]")
    roughen_deg: float = Field(0.1, ge=0, description="floor of the resampling kernel's heading spread, deg [0.1]")
    seed: int = Field(0, description="seed of the filter's random stream [0]")


def _rot_batch(yaw: np.ndarray) -> np.ndarray:
    """(N, 3, 3) block-diagonal rotations diag(R(yaw), 1)."""
    c, s = np.cos(yaw), np.sin(yaw)
    out = np.zeros((len(yaw), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1], out[:, 2, 2] = c, -s, s, c, 1.0
    return out


class Pf(Estimator):
    """Particle filter over (pose, clone pose, body velocity); with an IMU each particle also carries a gyro yaw-rate
    bias and its yaw follows the gyro less that bias plus the gyro's noise; a compass heading reweights the particles."""

    name = "pf"
    takes_inertial = True

    def __init__(self, params: PfParams, monitor: Monitor) -> None:
        super().__init__(params, monitor)
        self.params: PfParams = params
        self.rng = stream(params.seed, "fusion.pf")
        n = params.n_particles
        self.poses = np.zeros((n, 3))
        self.clones = np.zeros((n, 3))
        self.vel = np.zeros((n, 3))
        self.logw = np.full(n, -math.log(n))
        self.bias = np.zeros((n, 2))  # per-particle mean of the receiver's correlated error
        self.bias_cov = np.zeros((2, 2))  # its covariance, shared
        self._bias_var = 0.0
        self._taken = 0.0  # per-axis variance of the receiver's correlated error the estimate took in from its fixes
        self._taken_with_bias = 0.0  # its covariance with the receiver's correlated error now
        self._coast_cov = np.zeros((3, 3))  # process spread accumulated since the clone, body frame
        self._clone_stamp = 0.0
        self.gyro_bias = np.zeros(n)  # per particle, rad/s (with an IMU)
        self._init = False
        self._q = np.array([params.accel_sigma**2, params.lateral_accel_sigma**2, math.radians(params.yaw_accel_sigma_deg) ** 2])

    @property
    def initialized(self) -> bool:
        return self._init

    @property
    def weights(self) -> np.ndarray:
        w = np.exp(self.logw - self.logw.max())
        return w / w.sum()

    def _initialise(self, alignment: Alignment) -> None:
        n = self.params.n_particles
        chol = np.linalg.cholesky(alignment.cov + 1e-12 * np.eye(3))
        self.poses = alignment.pose + self.rng.standard_normal((n, 3)) @ chol.T
        self.poses[:, 2] = wrap_angle(self.poses[:, 2])
        velocity = self.odometry.velocity()
        mean, var = (np.zeros(3), np.array([1.0, 1.0, 0.01])) if velocity is None else (velocity[0].copy(), np.diag(velocity[1]).copy())
        ground = alignment.start_velocity(velocity, self.params.init_velocity_sigma_mps)
        if ground is not None:  # the receiver's velocity where the odometry did not see the motion
            mean[:2], var[:2] = ground[0], np.diag(ground[1])
        sigma = np.sqrt(np.clip(var, [0.25, 0.25, 1e-4], [9.0, 9.0, 0.1]))  # as uncertain as the last step, within bounds
        self.vel = mean + self.rng.standard_normal((n, 3)) * sigma
        self.clones = self.poses.copy()
        self._clone_stamp = alignment.stamp
        now, last_pose, last_stamp = self.odometry.pose_at(alignment.stamp), self.odometry.last_pose, self.odometry.last_stamp
        if now is not None and last_pose is not None and last_stamp is not None and last_stamp == self._ref_stamp:
            back = between(now, last_pose)  # from now back to the reference scan, body frame
            rot = _rot_batch(self.poses[:, 2])
            self.clones = self.poses + np.einsum("nij,j->ni", rot, back)
            self.clones[:, 2] = wrap_angle(self.clones[:, 2])
            self._clone_stamp = last_stamp
        self._coast_cov = np.zeros((3, 3))
        self.logw = np.full(n, -math.log(n))
        self.bias = np.zeros((n, 2))
        self.bias_cov = np.eye(2) * self._bias_var
        self._taken = self._taken_with_bias = 0.0  # the cloud is drawn from the alignment's covariance, the fixes' error in it
        if self.uses_imu and not self._init:  # a re-alignment keeps the particles' gyro biases
            self.gyro_bias = math.radians(self.inertial.gyro_bias_sigma_dps) * self.rng.standard_normal(n)
        self._init = True

    def _predict(self, stamp: float, yaw_step: float | None = None) -> None:
        dt = stamp - self.stamp
        if dt <= 0.0:
            return
        n = self.params.n_particles
        dv = self.rng.standard_normal((n, 3)) * np.sqrt(self._q * dt)
        body = (self.vel + 0.5 * dv) * dt
        coast = np.diag(self._q) * dt**3 / 3.0
        if self._gyro_rate is not None and self.uses_imu:
            step = self._gyro_rate * dt if yaw_step is None else yaw_step
            walk = math.radians(self.inertial.gyro_bias_walk_dph) / 3600.0 / 60.0
            draw = self.rng.standard_normal((n, 2))
            yaw_noise = math.hypot(self._gyro_noise, math.radians(self.inertial.particle_yaw_walk_dps))
            body[:, 2] = step - self.gyro_bias * dt + yaw_noise * math.sqrt(dt) * draw[:, 0]
            self.gyro_bias += walk * math.sqrt(dt) * draw[:, 1]
            dv[:, 2] = self._gyro_rate - self.gyro_bias - self.vel[:, 2]
            coast[2, 2] = yaw_noise**2 * dt
        c, s = np.cos(self.poses[:, 2]), np.sin(self.poses[:, 2])
        self.poses[:, 0] += c * body[:, 0] - s * body[:, 1]
        self.poses[:, 1] += s * body[:, 0] + c * body[:, 1]
        self.poses[:, 2] = wrap_angle(self.poses[:, 2] + body[:, 2])
        self.vel += dv
        self._coast_cov += coast
        if self.params.gps_correlation_s > 0:
            rho = math.exp(-dt / self.params.gps_correlation_s)
            self._taken_with_bias *= rho
            if self._correlated():
                self.bias *= rho
                self.bias_cov = rho**2 * self.bias_cov + np.eye(2) * self._bias_var * (1.0 - rho**2)

    def _odometry(self, stamp: float, step: np.ndarray, step_cov: np.ndarray) -> str:
        if not self._init:
            return ""
        rot = _rot_batch(self.clones[:, 2])
        mu_o = self.clones + np.einsum("nij,j->ni", rot, step)
        cov_o = rot @ step_cov @ rot.transpose(0, 2, 1)
        cov_cv = rot @ (self._coast_cov + np.diag([1e-8, 1e-8, 1e-10])) @ rot.transpose(0, 2, 1)
        r = mu_o - self.poses
        r[:, 2] = wrap_angle(r[:, 2])
        S = cov_cv + cov_o
        S_inv = np.linalg.inv(S)
        K = cov_cv @ S_inv
        mean = self.poses + np.einsum("nij,nj->ni", K, r)
        post = cov_cv - K @ cov_cv
        post = 0.5 * (post + post.transpose(0, 2, 1)) + 1e-14 * np.eye(3)
        chol = np.linalg.cholesky(post)
        self.poses = mean + np.einsum("nij,nj->ni", chol, self.rng.standard_normal((len(mean), 3)))
        self.poses[:, 2] = wrap_angle(self.poses[:, 2])
        _, logdet = np.linalg.slogdet(S)
        self.logw += -0.5 * (np.einsum("ni,nij,nj->n", r, S_inv, r) + logdet)
        dt = stamp - self._clone_stamp
        if dt > 0:
            d = self.poses - self.clones
            d[:, 2] = wrap_angle(d[:, 2])
            back = np.einsum("nji,nj->ni", rot, d)  # into each clone's body frame
            self.vel = back / dt
        self._after_weighting()
        self._reanchor(stamp)
        return ""

    def _reanchor(self, stamp: float) -> None:
        if self._init:
            self.clones = self.poses.copy()
            self._clone_stamp = stamp
            self._coast_cov = np.zeros((3, 3))

    def _antennas(self) -> np.ndarray:
        c, s = np.cos(self.poses[:, 2]), np.sin(self.poses[:, 2])
        lx, ly = self.lever
        return self.poses[:, :2] + np.column_stack([c * lx - s * ly, s * lx + c * ly])

    def _correlated(self) -> bool:
        return self.params.bias_state and self.params.gps_correlation_s > 0

    def _observe_fix(self, obs: FixObservation) -> None:
        """The receiver's error variance follows its HDOP (the bias's process noise uses it)."""
        var = self.params.bias_variance(float(np.trace(obs.cov)) / 2.0)
        if self._correlated() and self._init and self._bias_var == 0.0:
            self.bias_cov = np.eye(2) * var  # initialised before any fix: as uncertain as the receiver
        if self._bias_var > 0.0:  # the receiver's error follows its HDOP (Ekf._set_bias_level): so does what it shares
            self._taken_with_bias *= math.sqrt(var / self._bias_var)
        self._bias_var = var

    def _update_fix(self, obs: FixObservation) -> None:
        nu = self.params.gps_dof
        if not self._correlated():
            antennas = self._antennas()
            tracked = self.params.gps_correlation_s > 0  # independent fixes share nothing that averaging leaves
            before = self._spread(antennas) if tracked else 0.0
            r = obs.xy - antennas
            d2 = np.einsum("ni,ij,nj->n", r, np.linalg.inv(obs.cov + np.eye(2) * obs.allowance_m**2), r)
            self.logw += -0.5 * (nu + 2.0) * np.log1p(d2 / nu)
            if before > 0.0:
                self._take_in(1.0 - self._spread(antennas) / before)
            self._after_weighting()
            return
        S = self.bias_cov + np.eye(2) * (self.params.gps_white_sigma_m**2 + obs.allowance_m**2)
        S_inv = np.linalg.inv(S)
        r = obs.xy - self._antennas() - self.bias
        d2 = np.einsum("ni,ij,nj->n", r, S_inv, r)
        self.logw += -0.5 * (nu + 2.0) * np.log1p(d2 / nu)
        gain = self.bias_cov @ S_inv
        self.bias += ((nu + 2.0) / (nu + d2))[:, None] * (r @ gain.T)
        self.bias_cov = (np.eye(2) - gain) @ self.bias_cov
        self._after_weighting()

    def _take_in(self, gain: float) -> None:
        """A fix moved the estimate by `gain` (the share its cloud's spread shrank by) towards its position: the estimate
        took in that share of the receiver's correlated error (the module docstring's consider covariance)."""
        k, b = min(max(gain, 0.0), 1.0), self._bias_var
        self._taken = (1.0 - k) ** 2 * self._taken + 2.0 * k * (1.0 - k) * self._taken_with_bias + k * k * b
        self._taken_with_bias = (1.0 - k) * self._taken_with_bias + k * b

    def _spread(self, values: np.ndarray) -> float:
        """Total weighted variance of (N, 2) positions under the current weights (the trace of their covariance)."""
        return float(np.trace(self._mean_cov(values, None)[1]))

    def _after_weighting(self) -> None:
        self.logw -= self.logw.max()
        w = self.weights
        self.logw = np.log(np.maximum(w, 1e-300))
        ess = 1.0 / float(np.sum(w**2))
        n = self.params.n_particles
        if ess < self.params.resample_ess * n:
            mean, spread = self._mean_cov(self.poses, 2)
            u = (self.rng.random() + np.arange(n)) / n
            idx = np.minimum(np.searchsorted(np.cumsum(w), u), n - 1)
            # regularised resampling (Liu-West): shrink towards the mean and add a kernel shaped like
            # the posterior, which keeps its mean and spread, plus a small floor, so that
            # near-deterministic motion does not collapse the cloud
            h2 = (4.0 / (n * 5.0)) ** (2.0 / 7.0)
            shrink = math.sqrt(1.0 - h2)
            floor = np.diag([self.params.roughen_m**2, self.params.roughen_m**2, math.radians(self.params.roughen_deg) ** 2])
            chol = np.linalg.cholesky(h2 * spread + floor)
            offset = self.poses[idx] - mean
            offset[:, 2] = wrap_angle(offset[:, 2])
            jitter = (shrink - 1.0) * offset + self.rng.standard_normal((n, 3)) @ chol.T
            self.poses = self.poses[idx] + jitter
            self.poses[:, 2] = wrap_angle(self.poses[:, 2])
            self.clones = self.clones[idx] + jitter
            self.clones[:, 2] = wrap_angle(self.clones[:, 2])
            self.vel = self.vel[idx]
            self.bias = self.bias[idx]
            self.gyro_bias = self.gyro_bias[idx]
            self.logw = np.full(n, -math.log(n))

    def _relock(self, obs: FixObservation) -> None:
        n = self.params.n_particles
        mean, _ = self._mean_cov(self.poses, 2)
        target = obs.xy - np.array([[math.cos(mean[2]), -math.sin(mean[2])], [math.sin(mean[2]), math.cos(mean[2])]]) @ self.lever
        spread = self.rng.standard_normal((n, 2)) @ np.linalg.cholesky(obs.cov).T
        moved = target - self.poses[:, :2] + spread
        self.poses[:, :2] += moved
        self.clones[:, :2] += moved
        self.bias[:] = 0.0
        self.bias_cov = np.eye(2) * self._bias_var
        self._taken = self._taken_with_bias = 0.0  # the cloud is spread by the fix's whole covariance
        self.logw = np.full(n, -math.log(n))

    def _mean_cov(self, values: np.ndarray, angular: int | None) -> tuple[np.ndarray, np.ndarray]:
        w = self.weights
        mean = w @ values
        if angular is not None:
            mean[angular] = math.atan2(float(w @ np.sin(values[:, angular])), float(w @ np.cos(values[:, angular])))
        d = values - mean
        if angular is not None:
            d[:, angular] = wrap_angle(d[:, angular])
        return mean, (d * w[:, None]).T @ d

    def _start_gyro(self) -> None:
        """Nothing to rewire: the particles' yaw follows the gyro from the next prediction on."""

    def _update_heading(self, measured: float, innovation: float, var: float) -> None:
        r = wrap_angle(measured - self.poses[:, 2])
        self.logw += -0.5 * r**2 / var
        self._after_weighting()

    def _restart(self) -> None:
        self._init = False

    def _pose3(self) -> np.ndarray:
        return self._mean_cov(self.poses, 2)[0]

    def _cov3(self) -> np.ndarray:
        """The cloud's spread plus the receiver's correlated error the estimate took in (the consider covariance)."""
        cov = self._mean_cov(self.poses, 2)[1]
        cov[0, 0] += self._taken
        cov[1, 1] += self._taken
        return cov

    def _predicted_antenna(self, obs: FixObservation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        if not self._correlated():
            return (*self._mean_cov(self._antennas(), None), obs.cov)
        mean, cov = self._mean_cov(self._antennas() + self.bias, None)
        return mean, cov + self.bias_cov, np.eye(2) * self.params.gps_white_sigma_m**2

    def _body_velocity(self) -> np.ndarray:
        return self.weights @ self.vel[:, :2]

    def _body_velocity_cov(self) -> np.ndarray:
        spread = self.vel[:, :2] - self._body_velocity()
        return (spread * self.weights[:, None]).T @ spread

    def _heading(self) -> tuple[float, float]:
        mean, cov = self._mean_cov(self.poses, 2)
        return float(mean[2]), float(cov[2, 2])
