"""Estimator base: input screening, time order, odometry conversion, monitor plumbing, recorded events."""

from __future__ import annotations

import math

import numpy as np
from scipy.stats import chi2

from fusion.bootstrap import HEADING_FROM_COMPASS, HEADING_FROM_COURSE, HEADING_GIVEN, HEADING_UNKNOWN, Alignment, Bootstrap
from fusion.compass_check import CompassGyroBudget, CompassGyroCheck
from fusion.geometry import drot2, is_psd, lidar_to_base, planar, pose_matrix, rot2, tilt_rate
from fusion.integrity import protection_level
from fusion.monitors import FixContext, Monitor
from fusion.observation import FixObservation, allowing, screen, screen_rule
from fusion.odometry import OdometryTrack
from fusion.params import EstimatorParams, InertialParams
from fusion.verdict import Event, Verdict
from matcher.result import MatchResult
from riverbench.angles import wrap_angle
from riverbench.samples import HeadingSample, ImuSamples
from sim.gnss_fix import GnssFix

EARTH_RATE = 7.292115e-5
"""WGS-84 Earth rotation rate, rad/s (NIMA TR8350.2)."""
UNOBSERVED_VAR = 1e6
"""Variance (m^2) given to a match direction that carries no information."""
HEIGHT_WALK_M2_PER_S = 0.01
"""Random-walk rate of base_link height (water level, waves) in the height filter."""


TILT_RATE_AGE_S = 0.3
"""A match's roll and pitch rates stand for the hull's within this long of its stamp: a few revolutions at 10 Hz, a tenth
of a short wave's period (rough_water's are 3-5 s)."""

TILT_MEAN_S = 10.0
"""Time constant of the running mean taken out of the matches' roll and pitch rates before they swing the antenna
(Estimator._antenna_sway), s. A floating hull rolls and pitches about its hydrostatic equilibrium, which the restoring
moment of its waterplane holds (Faltinsen 1990, Sea Loads on Ships and Offshore Structures, ch. 2 and 5): over a few wave
periods its tilt rates average to zero, so their mean is the matcher's drift, not the antenna's motion. 10 s is longer
than the longest period of the seas modelled (sim.waves: JONSWAP components down to 0.6 of the peak frequency, 8 s at
rough_water's 5 s peak), so the waves pass (a first-order high-pass, 0.99 of an 8 s period's amplitude) and a drift
lasting longer is removed. rough_water seed 1: gicp's chained pitch drifted -30 deg in 100 s in the canal (-0.8 deg/s
for 25 s), and taken as the hull's it moved the ekf's speed 0.018 m/s ahead of the Doppler's, 1.2 m ahead in 100 s."""


class Estimator:
    """Fed fixes and matches in time order; `.pose` is world<-base_link now, `.cov` the 3x3
    covariance of (x, y, yaw). Inputs it cannot use are recorded in `.events`, never raised."""

    name = "estimator"
    uses_odometry = True
    """False for an estimator that ignores scan matching (the drive then needs no matcher for it)."""
    takes_inertial = False
    """True for an estimator that can be fed IMU samples and compass headings (sensors imu, compass)."""

    def __init__(self, params: EstimatorParams, monitor: Monitor) -> None:
        if not self.takes_inertial and {"imu", "compass"} & set(params.sensors):
            raise ValueError(f"estimator '{self.name}': sensors: it uses no imu or compass (the ekf and the pf do)")
        self.params = params
        self.monitor = monitor
        self.mount = np.asarray(params.mount, dtype=float)
        self.antenna = np.asarray(params.antenna, dtype=float)
        self.lever = self.antenna[:2].copy()
        self.events: list[Event] = []
        self.stamp = -math.inf
        self.odometry = OdometryTrack()
        self._bootstrap = Bootstrap(params.init_baseline_m, params.init_min_fixes, params.init_max_hdop, self.lever, params.init_max_yaw_sd_deg)
        self._height = 0.0
        self._height_var = math.inf
        sxy, syaw = params.default_odom_sigma_m, math.radians(params.default_odom_sigma_yaw_deg)
        self._default_odom_cov = np.diag([sxy**2, sxy**2, sxy**2, syaw**2, syaw**2, syaw**2])
        self.inertial: InertialParams = getattr(params, "inertial", None) or InertialParams()
        self.uses_imu = "imu" in params.sensors
        fxy, fyaw = params.odom_floor_sigma_m, math.radians(params.odom_floor_sigma_yaw_deg)
        if self.uses_imu:
            fyaw = math.radians(self.inertial.odom_floor_sigma_yaw_deg)
        self._odom_floor = np.diag([fxy**2, fxy**2, fyaw**2])
        self._refused_since: float | None = None  # first refused fix of an unbroken refused run
        self._own_start = params.initial_pose is not None  # started from a given pose, not the fixes (FixContext.own_start)
        self._ref_stamp: float | None = None
        self._tilt_rate: tuple[float, np.ndarray] | None = None  # (stamp, roll and pitch rate vector, rad/s) of the last match
        self._tilt_mean = np.zeros(3)  # running mean of those rates, their drift (TILT_MEAN_S): from zero, a hull at rest
        self._last_measured: float | None = None
        self._gyro_rate: float | None = None  # the latest measured yaw rate (rad/s): yaw follows the gyro once it is set
        self._gyro_noise = 0.0  # its white noise density, rad/s/sqrt(Hz)
        self._imu_last: float | None = None
        self._heading_last = -math.inf
        self._gyro_yaw = 0.0  # the gyro's integral (raw rates less the Earth's), rad, not wrapped: what the compass check compares
        ip = self.inertial
        self._compass_gate = float(chi2.ppf(ip.compass_gate_prob, 1))  # once: scipy's ppf costs 0.2 ms a heading
        checks = self.uses_imu and "compass" in params.sensors and ip.compass_gyro_check
        walk = math.radians(ip.gyro_bias_walk_dph) / 3600.0 / 60.0
        budget = CompassGyroBudget(
            ip.compass_iron_share,
            walk,
            ip.compass_check_fit_s,
            ip.compass_check_average_s,
            ip.compass_check_min_headings,
            math.sqrt(self._compass_gate),
        )
        self._compass_check = CompassGyroCheck(budget) if checks else None
        self.heading_from = ""
        """What gave the heading (fusion.bootstrap.HEADING_*; '' before the estimator starts): a vessel that starts at rest
        has its position first and its heading unknown until motion, a compass or the receiver's course gives it."""
        self.position_at = math.nan
        """When the estimator first had a pose (s)."""
        self.heading_at = math.nan
        """When it first had a heading (s; NaN while it has none)."""

    # ---- public API -------------------------------------------------------------------------
    @property
    def initialized(self) -> bool:
        raise NotImplementedError

    @property
    def pose(self) -> np.ndarray:
        """4x4 world<-base_link at the latest input (NaN before initialisation)."""
        if not self.initialized:
            return np.full((4, 4), np.nan)
        x, y, yaw = self._pose3()
        return pose_matrix(x, y, self._height - self.antenna[2] if math.isfinite(self._height_var) else 0.0, yaw)

    @property
    def cov(self) -> np.ndarray:
        """3x3 covariance of (x, y, yaw) (infinite before initialisation)."""
        if not self.initialized:
            return np.full((3, 3), np.inf)
        return self._cov3()

    @property
    def protection_level(self) -> float:
        """Horizontal protection level (m) at the params' integrity risk (fusion.integrity; NaN before initialisation)."""
        if not self.initialized:
            return math.nan
        return protection_level(self._cov3()[:2, :2], self.params.integrity_risk)

    def add_fix(self, fix: GnssFix) -> Verdict:
        """Use one receiver output; return the monitor's verdict (untrusted fixes are not used)."""
        stamp = getattr(fix, "stamp", math.nan)
        refused = self._refuse_stamp(stamp, "fix")
        if refused:
            return Verdict(False, math.nan, refused, rule="input.stamp")
        obs, why = screen(fix, self.params.uere_m, self.params.accept_dead_reckoning)
        self._advance(float(stamp))
        if obs is None:
            if why.startswith("bad field") or why.startswith("unsupported"):
                self.events.append(Event(float(stamp), "fix", why))
            self.monitor.note_outage(float(stamp))
            self._observe_outage()
            rule = screen_rule(why)
            return Verdict(False, math.inf if rule == "input.dead_reckoning" else math.nan, why, rule=rule)
        self._observe_fix(obs)
        if self.params.initial_pose is None:
            self._bootstrap.add(obs, self.odometry)
        if not self.initialized:
            self._try_initialise(obs)
        elif self.heading_from == HEADING_UNKNOWN:
            self._find_heading(obs)
        ctx = self._context(obs)
        verdict = self.monitor.check(obs, ctx)
        self.monitor.commit(obs, verdict)
        try:
            self._use_fix(allowing(obs, verdict.allowance_m) if verdict.trusted else obs, verdict)
        except np.linalg.LinAlgError as err:  # a numerically broken update: skip it, keep running
            self.events.append(Event(obs.stamp, "fix", f"GPS update failed: {err}"))
        if self.initialized and verdict.trusted:
            try:
                self._use_velocity(obs)
            except np.linalg.LinAlgError as err:
                self.events.append(Event(obs.stamp, "fix", f"GPS velocity update failed: {err}"))
        self._watch_lock(obs, verdict)
        self._check_finite(obs.stamp, "fix")
        self._last_measured = obs.stamp
        return verdict

    def _check_finite(self, stamp: float, source: str) -> None:
        """A filter whose state went non-finite starts over from the next alignment (recorded)."""
        if self.initialized and not (np.all(np.isfinite(self._pose3())) and np.all(np.isfinite(self._cov3()))):
            self.events.append(Event(stamp, source, "filter state became non-finite: starting over"))
            self._restart()

    def _restart(self) -> None:
        """Drop the estimate; the next alignment initialises again."""
        raise NotImplementedError

    def _watch_lock(self, obs: FixObservation, verdict: Verdict) -> None:
        """Re-lock onto GPS when every fix has been refused for relock_s while fixes kept coming, onto a
        fix refused only for disagreeing with the filter (one refused on its own evidence, such as
        an NLOS C/N0, is no sign that the filter diverged, and no place to re-lock onto)."""
        gap = self._last_measured is None or obs.stamp - self._last_measured > 2.0
        if verdict.on_its_own and not gap:
            return
        if not verdict.steady and not verdict.trusted and not gap:
            # a fix that jumps against the odometry or carries a suspect satellite: the receiver, not the filter, may be
            # astray (a reflected signal smoothed into a ramp), so the clock restarts (quickstart: a re-lock onto a fix
            # 30 m into such a ramp at 1767 s)
            self._refused_since = None
            return
        if verdict.trusted or not self.initialized or gap:
            self._refused_since = None if verdict.trusted or gap else self._refused_since
            return
        if self._refused_since is None:
            self._refused_since = obs.stamp
        elif obs.stamp - self._refused_since >= self.params.relock_s:
            fresh = self._bootstrap.alignment(obs.stamp) if self.params.initial_pose is None else None
            how = "re-aligned pose and heading" if fresh is not None else "moved the position"
            self.events.append(Event(obs.stamp, "fix", f"re-locked onto GPS after {obs.stamp - self._refused_since:.0f} s of refused fixes: {how}"))
            if fresh is not None:
                self._start(fresh)
            else:
                self._relock(obs)
            self.monitor.reset()
            self._refused_since = None
            self._own_start = False

    def _observe_outage(self) -> None:
        """An epoch without a measured position (filters with a GPS error model may relax it)."""

    def _relock(self, obs: FixObservation) -> None:
        """Move the position onto this fix with its uncertainty (heading and motion kept)."""

    def _use_velocity(self, obs: FixObservation) -> str:
        """Update with the receiver's velocity over ground (filters that model it override); why it was not used."""
        return "no velocity model"

    def _use_fix(self, obs: FixObservation, verdict: Verdict) -> None:
        """Update with a fix the monitor trusts (gps_only overrides: it takes every fix)."""
        if verdict.trusted and self.initialized:
            self._update_fix(obs)
            self._update_height(obs)

    def add_match(self, scan_stamp: float, result: MatchResult) -> None:
        """Use one scan's match: its motion since the matcher's reference scan, in the lidar frame."""
        refused = self._refuse_stamp(scan_stamp, "match")
        if refused:
            return
        stamp = float(scan_stamp)
        self._advance(stamp)
        ok = bool(getattr(result, "ok", False))
        info = getattr(result, "info", None) or {}
        if not ok:
            reason = str(info.get("reason", "no reason given"))
            self.events.append(Event(stamp, "match", f"matcher '{self.params.matcher}' failed: {reason}"))
            if not info.get("gated", False):
                self._new_reference(stamp)  # the matcher restarts tracking from this scan
            return
        step, step_cov, why, rotation = self._planar_step(result)
        if self._ref_stamp is None:
            why = why or "no reference scan seen before this match"
        if why:
            self.events.append(Event(stamp, "match", why))
            self._new_reference(stamp)
            return
        step_cov = self._slip_allowance(stamp, step, step_cov)
        try:
            rejected = self._odometry(stamp, step, step_cov)
        except np.linalg.LinAlgError as err:  # a numerically broken update: skip it, keep running
            rejected = f"odometry update failed: {err}"
        if rejected:
            self.events.append(Event(stamp, "match", rejected))
            self._new_reference(stamp)
            return
        self._check_finite(stamp, "match")
        self.odometry.add(stamp, step, step_cov)
        assert self._ref_stamp is not None  # a match without one returned above
        previous, self._tilt_rate = self._tilt_rate, (stamp, tilt_rate(rotation, stamp - self._ref_stamp))
        if previous is not None:  # from zero, not the first rate: one wave's roll taken as the drift swayed rough_water seed 2 1.3 m in 10 s
            weight = 1.0 - math.exp(-max(stamp - previous[0], 0.0) / TILT_MEAN_S)
            self._tilt_mean = self._tilt_mean + weight * (self._tilt_rate[1] - self._tilt_mean)
        self._ref_stamp = stamp
        if not self.initialized and self.params.initial_pose is not None:
            self._initialise_from_params(stamp, self.params.initial_pose)

    @property
    def wants_scans(self) -> bool:
        """Whether its monitor maps what the LiDAR sees, so add_scan should be fed each scan's points."""
        return self.monitor.wants_scans

    def add_scan(self, scan_stamp: float, points: np.ndarray) -> None:
        """One scan's points (N, 3, lidar frame), after add_match of the same scan, for a monitor that maps what the
        LiDAR sees; placed with the filter's pose at the waterline (a vessel floats: its base_link height is known
        better than the receiver's, whose vertical error moves by metres beside walls)."""
        if not self.monitor.wants_scans or not self.initialized or float(scan_stamp) != self.stamp:
            return
        base = np.asarray(points, dtype=float) @ self.mount[:3, :3].T + self.mount[:3, 3]
        self.monitor.add_scan(self.stamp, self._level_pose(), base)

    def _level_pose(self) -> np.ndarray:
        """world<-base_link now with base_link at the waterline (z = 0)."""
        x, y, yaw = self._pose3()
        return pose_matrix(x, y, 0.0, yaw)

    def add_imu(self, samples: ImuSamples) -> None:
        """Use a batch of IMU samples in time order: from the first on, yaw follows the gyro (its yaw rate, levelled with
        the roll and pitch the accelerometer's mean over the batch shows) and a yaw-rate bias is estimated."""
        if not len(samples):
            return
        if self._refuse_stamp(samples.stamp[-1], "imu"):
            return
        stamps = np.asarray(samples.stamp, dtype=float)
        gyro, accel = np.asarray(samples.gyro, dtype=float), np.asarray(samples.accel, dtype=float)
        if not (np.all(np.isfinite(stamps)) and np.all(np.isfinite(gyro)) and np.all(np.isfinite(accel))):
            self.events.append(Event(float(stamps[-1]), "imu", "bad field: non-finite IMU sample"))
            return
        f = accel.mean(axis=0)
        roll, pitch = math.atan2(f[1], f[2]), math.atan2(-f[0], math.hypot(f[1], f[2]))
        earth = EARTH_RATE * math.sin(math.radians(self.inertial.latitude_deg))
        rates = (math.sin(roll) * gyro[:, 1] + math.cos(roll) * gyro[:, 2]) / math.cos(pitch) - earth
        # each sample stands for the period that ends at its stamp; only what lies after the filter's time is new
        starts = np.r_[
            self._imu_last if self._imu_last is not None else stamps[0] - (np.median(np.diff(stamps)) if len(stamps) > 1 else 0.0), stamps[:-1]
        ]
        spans = np.clip(stamps - np.maximum(starts, self.stamp), 0.0, None)
        noise = self.inertial.gyro_noise_dps
        self._gyro_noise = math.radians(noise) if noise is not None else float(samples.gyro_noise)
        self._imu_last = float(stamps[-1])
        self._gyro_yaw += float(rates @ (stamps - starts))
        first = self._gyro_rate is None
        self._gyro_rate = float(rates[-1])
        if first:
            self._start_gyro()
        stamp = float(stamps[-1])
        if self.initialized and stamp > self.stamp:
            self._predict(stamp, float(rates @ spans))
        self.stamp = max(self.stamp, stamp)
        self._check_finite(stamp, "imu")

    def add_heading(self, sample: HeadingSample) -> bool:
        """Use a compass heading; False when it is not used (before initialisation, between used ones, or refused as
        disturbed: its field differs from the undisturbed one, its innovation lies beyond the gate, or, with an IMU, its
        change disagrees with the gyro's: fusion.compass_check)."""
        if self._refuse_stamp(getattr(sample, "stamp", math.nan), "heading"):
            return False
        stamp = float(sample.stamp)
        self._advance(stamp)
        p = self.inertial
        if not self.initialized or not sample.finite:
            return False
        if abs(sample.field_norm_ut / p.field_ut - 1.0) > p.field_tolerance or abs(sample.dip_deg - p.dip_deg) > p.dip_tolerance_deg:
            return False
        sigma = math.radians(p.compass_sigma_deg) if p.compass_sigma_deg is not None else float(sample.sigma)
        if self.heading_from == HEADING_UNKNOWN:  # started at rest: the first undisturbed compass heading is the heading
            self._set_heading(stamp, float(sample.yaw), sigma**2, HEADING_FROM_COMPASS)
            self._heading_last = stamp
            return True
        heading = self._heading()
        if heading is None:
            return False
        yaw, var = heading
        innovation = wrap_angle(float(sample.yaw) - yaw)
        if innovation**2 / (var + sigma**2) > self._compass_gate:
            return False
        # every heading past the field and innovation checks goes to the gyro comparison, at the gyro's latest time
        check = self._compass_check
        if check is not None and self._imu_last is not None and not check.check(self._imu_last, float(sample.yaw), self._gyro_yaw, self._gyro_noise):
            return False
        if stamp - self._heading_last < p.compass_interval_s:
            return False
        try:
            self._update_heading(float(sample.yaw), innovation, sigma**2)
        except np.linalg.LinAlgError as err:
            self.events.append(Event(stamp, "heading", f"compass update failed: {err}"))
            return False
        self._heading_last = stamp
        self._check_finite(stamp, "heading")
        return True

    def _start_gyro(self) -> None:
        """The first IMU sample arrived: yaw follows the gyro from now on."""
        raise NotImplementedError(f"{self.name} does not use IMU samples")

    def _update_heading(self, measured: float, innovation: float, var: float) -> None:
        """Correct the heading by a compass heading `measured` (rad; `innovation` against the estimate) of variance var."""
        raise NotImplementedError(f"{self.name} does not use compass headings")

    # ---- shared machinery -------------------------------------------------------------------
    def _refuse_stamp(self, stamp, source: str) -> str:
        try:
            t = float(stamp)
        except (TypeError, ValueError):
            t = math.nan
        if not math.isfinite(t):
            reason = f"bad field 'stamp'={stamp!r}"
        elif t < self.stamp:
            reason = f"out of order: stamp {t:.3f} before the latest input {self.stamp:.3f}"
        else:
            return ""
        self.events.append(Event(t if math.isfinite(t) else self.stamp, source, reason))
        return reason

    def _planar_step(self, result: MatchResult) -> tuple[np.ndarray, np.ndarray, str, np.ndarray]:
        """The match's planar step (dx, dy, dyaw) in base_link, its 3x3 covariance, why it cannot be used ('' when it
        can) and its whole rotation in base_link (3x3: the roll and pitch the planar step leaves out)."""
        T = np.asarray(getattr(result, "T", None), dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            return np.zeros(3), np.zeros((3, 3)), "match T is not a finite 4x4 matrix", np.eye(3)
        cov = getattr(result, "cov", None)
        cov = self._default_odom_cov if cov is None else np.asarray(cov, dtype=float)
        if cov.shape != (6, 6) or not is_psd(cov):
            return np.zeros(3), np.zeros((3, 3)), "match covariance is not a finite 6x6 PSD matrix", np.eye(3)
        T_base, cov_base = lidar_to_base(T, cov, self.mount)
        step, step_cov = planar(T_base, cov_base)
        step_cov = 0.5 * (step_cov + step_cov.T) + self._odom_floor + np.diag([1e-10, 1e-10, 1e-12])
        return step, self._drop_unobserved(step_cov), "", T_base[:3, :3]

    def _antenna_sway(self, stamp: float) -> np.ndarray:
        """The antenna's horizontal velocity (body frame, m/s) from the hull's roll and pitch rates, as the last match
        measured them (its rotation since the scan before) less their running mean (their drift, TILT_MEAN_S), within
        TILT_RATE_AGE_S of stamp; zero without one. A planar filter does not model roll and pitch, but in waves they swing
        an antenna on its mast: omega x r, with r the antenna's offset on base_link (rough_water, sea state 3: 0.17 m/s
        at the median, 0.33 at p95 for 1.3 m)."""
        if self._tilt_rate is None or abs(stamp - self._tilt_rate[0]) > TILT_RATE_AGE_S:
            return np.zeros(2)
        return np.cross(self._tilt_rate[1] - self._tilt_mean, self.antenna)[:2]

    def _slip_allowance(self, stamp: float, step: np.ndarray, step_cov: np.ndarray) -> np.ndarray:
        """Matchers on weakly constrained river scenes slip along the direction of motion with a tight
        covariance: a match that keeps less of the motion the filter expects along it than
        odom_slip_sigmas of its own sigma has that direction made unobserved; otherwise the variance
        along it is raised by (odom_slip_frac * the expected motion)^2."""
        velocity = self._body_velocity() if self.initialized else None
        if velocity is None or self._ref_stamp is None:
            return step_cov
        expected = velocity * (stamp - self._ref_stamp)
        length = float(np.hypot(*expected))
        if length == 0.0:
            return step_cov
        u = expected / length
        sigma = math.sqrt(float(u @ step_cov[:2, :2] @ u))
        k = self.params.odom_slip_sigmas
        slipped = k > 0 and length - float(u @ step[:2]) > k * sigma
        out = step_cov.copy()
        out[:2, :2] += UNOBSERVED_VAR * np.outer(u, u) if slipped else self.params.odom_slip_frac**2 * np.outer(expected, expected)
        return out

    def _body_velocity(self) -> np.ndarray | None:
        """The filter's (forward, left) speed in base_link, if it keeps one."""
        return None

    def _body_velocity_cov(self) -> np.ndarray | None:
        """The 2x2 covariance of _body_velocity, if the filter keeps one."""
        return None

    def _world_velocity_cov(self, heading: tuple[float, float] | None, body: np.ndarray | None) -> np.ndarray | None:
        """The covariance of the world velocity rot2(yaw) @ body: the body velocity's rotated, plus the heading's share."""
        cov = self._body_velocity_cov() if heading is not None and body is not None else None
        if cov is None or heading is None or body is None:
            return None
        rot, turn = rot2(heading[0]), drot2(heading[0]) @ body
        return rot @ cov @ rot.T + np.outer(turn, turn) * heading[1]

    def _drop_unobserved(self, step_cov: np.ndarray) -> np.ndarray:
        """Make translation directions the matcher barely observed 'unknown' (variance UNOBSERVED_VAR,
        uncorrelated with the rest) and cap the heading variance, so that no huge reported variance
        spoils the arithmetic."""
        values, vectors = np.linalg.eigh(step_cov[:2, :2])
        weak = values > self.params.odom_unobserved_sigma_m**2
        out = step_cov.copy()
        out[2, 2] = min(out[2, 2], math.pi**2)
        if not weak.any():
            return out
        basis = np.eye(3)
        basis[:2, :2] = vectors  # columns: the eigen-directions, then yaw
        local = basis.T @ out @ basis
        for i in np.flatnonzero(weak):
            local[i, :] = 0.0
            local[:, i] = 0.0
            local[i, i] = UNOBSERVED_VAR
        return basis @ local @ basis.T

    def _new_reference(self, stamp: float) -> None:
        self._ref_stamp = stamp
        self.odometry.anchor(stamp)
        self._reanchor(stamp)
        if not self.initialized and self.params.initial_pose is not None:
            self._initialise_from_params(stamp, self.params.initial_pose)

    def _try_initialise(self, obs: FixObservation) -> None:
        if self.params.initial_pose is not None:
            self._initialise_from_params(obs.stamp, self.params.initial_pose)
            return
        p = self.params
        alignment = self._bootstrap.alignment(obs.stamp) or self._bootstrap.at_rest(obs.stamp, p.init_static_speed_mps, p.init_static_s)
        if alignment is None and p.init_on_course:
            alignment = self._bootstrap.under_way(obs.stamp, p.init_course_speed_mps, math.radians(p.course_heading_sigma_deg) ** 2)
        if alignment is not None:
            self._start(alignment)

    def _find_heading(self, obs: FixObservation) -> None:
        """Started at rest, the heading unknown: take it from motion (the start-up alignment, once the travel gives one), else
        from the receiver's course over ground once the vessel makes init_course_speed_mps."""
        fresh = self._bootstrap.alignment(obs.stamp)
        if fresh is not None:
            self._start(fresh)
        elif obs.speed_mps >= self.params.init_course_speed_mps and math.isfinite(obs.course_deg):
            yaw = math.radians(90.0 - obs.course_deg)  # clockwise from north -> counter-clockwise from east
            self._set_heading(obs.stamp, yaw, math.radians(self.params.course_heading_sigma_deg) ** 2, HEADING_FROM_COURSE)

    def _set_heading(self, stamp: float, yaw: float, var: float, source: str) -> None:
        """Start over at the current position (and its covariance) with this heading."""
        x, y, _ = self._pose3()
        cov = self._cov3()
        cov[2, :] = cov[:, 2] = 0.0
        cov[2, 2] = var
        self._start(Alignment(stamp, np.array([x, y, float(wrap_angle(yaw))]), cov, source))

    def _start(self, alignment: Alignment) -> None:
        """Initialise (or start over) from `alignment`, noting when the pose and the heading came and what gave the heading."""
        self._initialise(alignment)
        self.heading_from = alignment.heading_from
        if math.isnan(self.position_at):
            self.position_at = alignment.stamp
        if math.isnan(self.heading_at) and alignment.heading_from != HEADING_UNKNOWN:
            self.heading_at = alignment.stamp

    def _initialise_from_params(self, stamp: float, initial_pose: tuple[float, float, float]) -> None:
        (x, y, yaw_deg), (sigma_m, sigma_deg) = initial_pose, self.params.initial_sigma
        cov = np.diag([sigma_m**2, sigma_m**2, math.radians(sigma_deg) ** 2])
        self._start(Alignment(stamp, np.array([x, y, math.radians(yaw_deg)]), cov, HEADING_GIVEN))

    def _update_height(self, obs: FixObservation) -> None:
        if not math.isfinite(self._height_var):
            self._height, self._height_var = obs.z, obs.z_var
            self._height_stamp = obs.stamp
            return
        var = self._height_var + HEIGHT_WALK_M2_PER_S * (obs.stamp - self._height_stamp)
        gain = var / (var + obs.z_var)
        self._height += gain * (obs.z - self._height)
        self._height_var = (1.0 - gain) * var
        self._height_stamp = obs.stamp

    def _context(self, obs: FixObservation) -> FixContext:
        predicted = self._predicted_antenna(obs) if self.initialized else None
        heading = self._heading() if self.initialized else None
        body = self._body_velocity() if heading is not None else None
        return FixContext(
            predicted=predicted,
            yaw=None if heading is None else heading[0],
            yaw_var=None if heading is None else heading[1],
            lever=self.lever,
            odometry=self.odometry,
            correlation_s=self.params.gps_correlation_s,
            velocity=None if heading is None or body is None else rot2(heading[0]) @ body,
            velocity_cov=self._world_velocity_cov(heading, body),
            antenna=(self._level_pose() @ np.r_[self.antenna, 1.0])[:3] if self.initialized else None,
            own_start=self._own_start,
        )

    def _advance(self, stamp: float) -> None:
        if self.initialized:
            self._predict(stamp)
        self.stamp = stamp

    # ---- what each estimator implements -----------------------------------------------------
    def _initialise(self, alignment: Alignment) -> None:
        raise NotImplementedError

    def _predict(self, stamp: float, yaw_step: float | None = None) -> None:
        """Propagate to `stamp`; with an IMU the yaw advances by yaw_step (the gyro's integral), else by the latest gyro rate."""
        raise NotImplementedError

    def _odometry(self, stamp: float, step: np.ndarray, step_cov: np.ndarray) -> str:
        """Use a planar base_link step from the reference scan; return a reason if it is refused."""
        raise NotImplementedError

    def _reanchor(self, stamp: float) -> None:
        """The matcher's reference moved to this scan without a usable step."""

    def _update_fix(self, obs: FixObservation) -> None:
        raise NotImplementedError

    def _observe_fix(self, obs: FixObservation) -> None:
        """Note a measured fix before it is judged (e.g. its HDOP sets the GPS error level)."""

    def _predicted_antenna(self, obs: FixObservation) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The fix the filter expects, the covariance of that prediction and the fix's noise."""
        raise NotImplementedError

    def _heading(self) -> tuple[float, float] | None:
        raise NotImplementedError

    def _pose3(self) -> np.ndarray:
        raise NotImplementedError

    def _cov3(self) -> np.ndarray:
        raise NotImplementedError
