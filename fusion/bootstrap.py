"""Start-up alignment: the odometry frame's rotation and offset in the world from the first GPS travel, or, for a vessel
at rest (moored at a pier), its position alone with the heading unknown until motion, a compass or a course gives it."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from fusion.geometry import compose, drot2, rot2
from fusion.observation import FixObservation
from fusion.odometry import OdometryTrack
from riverbench.angles import wrap_angle

UNKNOWN_YAW_VAR = np.pi**2 / 3.0
"""Variance of a heading known to be nothing better than uniform over the circle."""
HEADING_FROM_MOTION = "motion"
HEADING_UNKNOWN = "unknown (at rest: position only)"
HEADING_FROM_COMPASS = "compass"
HEADING_FROM_COURSE = "course over ground"
HEADING_GIVEN = "initial_pose"


@dataclass(frozen=True)
class Alignment:
    """World pose of base_link at `stamp`, its 3x3 covariance, what gave its heading (HEADING_*), and the receiver's
    velocity over ground at `stamp` (world east, north, m/s; None when the receiver gives none)."""

    stamp: float
    pose: np.ndarray
    cov: np.ndarray
    heading_from: str = HEADING_FROM_MOTION
    ground_velocity: np.ndarray | None = None

    def start_velocity(self, odometry: tuple[np.ndarray, np.ndarray] | None, gps_sigma_mps: float) -> tuple[np.ndarray, np.ndarray] | None:
        """The body velocity (forward, left) a filter starts with and its 2x2 covariance: the odometry's last step (3-vector
        and 3x3 covariance, as OdometryTrack.velocity gives them) fused with the receiver's velocity over ground, uncertain
        by gps_sigma_mps per axis (across the heading, also by its speed times the heading's own uncertainty: the body
        frame it is turned into is this alignment's), in information form. Where the matcher observed the motion its step dominates; where it
        left a direction unobserved (a degenerate match keeps its own constant-velocity prior there, 1e6 m^2) the
        receiver's velocity does, instead of a prior that never saw the motion (rough_water: gicp's 0.04 m/s against the
        boat's 2 m/s at start-up). None when neither is known."""
        ground = None if self.ground_velocity is None else rot2(-float(self.pose[2])) @ self.ground_velocity
        if ground is None:
            return None if odometry is None else (odometry[0][:2].copy(), odometry[1][:2, :2].copy())
        # turned into the body by a heading known to sigma_yaw, the receiver's velocity is that much less sure across it
        across = gps_sigma_mps**2 + float(ground @ ground) * max(float(self.cov[2, 2]), 0.0)
        cov_gps = np.diag(np.array([gps_sigma_mps**2, across]))
        info_gps = np.linalg.inv(cov_gps)
        if odometry is None:
            return ground, cov_gps
        mean, cov = odometry[0][:2], odometry[1][:2, :2]
        info_odo = np.linalg.pinv(0.5 * (cov + cov.T), hermitian=True)
        fused = np.linalg.inv(info_odo + info_gps)
        return fused @ (info_odo @ mean + info_gps @ ground), fused


@dataclass(frozen=True)
class _Sample:
    """One kept fix: its stamp, position, per-axis variance, the odometry pose at it (with the antenna lever applied) on
    odometry chain `segment` (None without odometry), and the receiver's speed over ground (NaN when it gives none) and
    velocity over ground (None when it gives none)."""

    stamp: float
    xy: np.ndarray
    var: float
    antenna_odo: np.ndarray | None
    segment: int | None
    speed_mps: float = np.nan
    ground_velocity: np.ndarray | None = None


class Bootstrap:
    """Collects fixes; `alignment(stamp)` fits rotation+translation of the odometry track onto them
    (2-D Procrustes) once they span `baseline_m`. Without odometry spanning the travel, the heading
    is the GPS course (the boat moving forward). Only the last `window_s` of fixes are kept; the fit
    is computed only when asked for (start-up, re-lock), not on every fix."""

    def __init__(
        self, baseline_m: float, min_fixes: int, max_hdop: float, lever: np.ndarray, max_yaw_sd_deg: float = 5.0, window_s: float = 120.0
    ) -> None:
        self.window_s = window_s
        self.max_yaw_var = np.radians(max_yaw_sd_deg) ** 2
        self.baseline_m = baseline_m
        self.min_fixes = min_fixes
        self.max_hdop = max_hdop
        self.lever = lever
        self._samples: list[_Sample] = []
        self._odo_at_last: np.ndarray | None = None  # odometry pose (x, y, yaw) at the latest kept fix
        self._segment: int | None = None  # every kept sample is on this odometry chain or on none

    def add(self, obs: FixObservation, odometry: OdometryTrack) -> None:
        """Keep one fix (fixes above max_hdop are not kept)."""
        if obs.hdop > self.max_hdop:
            return
        odo = odometry.pose_at(obs.stamp) if odometry.velocity() is not None else None
        segment = odometry.segment if odo is not None else None
        if segment is not None and segment != self._segment:  # fixes seen on an earlier (broken) chain no longer link to this one
            self._samples = [f if f.segment in (None, segment) else replace(f, antenna_odo=None, segment=None) for f in self._samples]
            self._segment = segment
        antenna = None if odo is None else odo[:2] + rot2(odo[2]) @ self.lever
        var = float(np.trace(obs.cov)) / 2.0
        self._samples.append(_Sample(obs.stamp, np.asarray(obs.xy, dtype=float), var, antenna, segment, obs.speed_mps, obs.ground_velocity))
        self._odo_at_last = odo
        cut = 0
        while self._samples[cut].stamp < obs.stamp - self.window_s:
            cut += 1
        del self._samples[:cut]

    def alignment(self, stamp: float) -> Alignment | None:
        """The alignment at the latest kept fix if it is at `stamp` and there is enough travel for a
        heading within max_yaw_sd_deg (judged from the fit's own residuals, so noisy fixes need more travel)."""
        if not self._samples or self._samples[-1].stamp != stamp:
            return None
        alignment = self._fit()
        if alignment is None or alignment.cov[2, 2] > self.max_yaw_var:
            return None
        return alignment

    def at_rest(self, stamp: float, static_speed_mps: float, static_s: float) -> Alignment | None:
        """The position of a vessel at rest, its heading unknown, when the latest kept fix is at `stamp` and the kept fixes
        show no motion: the last min_fixes all report a speed over ground below static_speed_mps, or (a receiver that
        reports none) those of the last static_s seconds, spanning it, all lie within baseline_m / 2 of their mean."""
        if len(self._samples) < self.min_fixes or self._samples[-1].stamp != stamp:
            return None
        last = self._samples[-self.min_fixes :]
        speeds = np.array([f.speed_mps for f in last])
        reported = bool(np.isfinite(speeds).all())
        recent = last if reported else [f for f in self._samples if f.stamp >= stamp - static_s]
        xy = np.array([f.xy for f in recent])
        centre = xy.mean(0)
        if reported:
            still = bool(np.all(speeds < static_speed_mps))
        else:
            spans = self._samples[0].stamp <= stamp - static_s
            still = spans and bool(np.all(np.hypot(*(xy - centre).T) <= self.baseline_m / 2.0))
        if not still:
            return None
        # the fixes' errors are correlated over tens of seconds: their mean is as uncertain as one; the lever's way is unknown
        sigma2 = float(np.mean([f.var for f in recent])) + float(self.lever @ self.lever)
        return Alignment(stamp, np.array([centre[0], centre[1], 0.0]), np.diag([sigma2, sigma2, UNKNOWN_YAW_VAR]), HEADING_UNKNOWN)

    def under_way(self, stamp: float, min_speed_mps: float, yaw_var: float) -> Alignment | None:
        """The pose of a vessel under way from the receiver's course over ground, its heading that course as uncertain as
        `yaw_var` (leeway and drift), when the latest kept fix is at `stamp` and the last min_fixes kept fixes all report
        a speed of at least min_speed_mps (the heading is their mean velocity's direction): a receiver's Doppler velocity
        gives the direction of travel at once, where the travel alignment waits for init_baseline_m of track (13 s on
        open_river, whose matcher sees nothing). The antenna sits at the fix; base_link is the lever back from it along
        that heading, so its position shares the heading's uncertainty through the lever."""
        if len(self._samples) < self.min_fixes or self._samples[-1].stamp != stamp:
            return None
        last = self._samples[-self.min_fixes :]
        velocities = [f.ground_velocity for f in last if f.ground_velocity is not None and f.speed_mps >= min_speed_mps]
        if len(velocities) < len(last):
            return None
        latest = last[-1]
        velocity = np.mean(velocities, axis=0)  # their white Doppler noise averages down
        yaw = float(np.arctan2(velocity[1], velocity[0]))
        xy = latest.xy - rot2(yaw) @ self.lever
        lever_yaw = -drot2(yaw) @ self.lever  # d(base_link xy) / d(yaw) at a fixed antenna
        cov = np.zeros((3, 3))
        cov[:2, :2] = np.eye(2) * latest.var + np.outer(lever_yaw, lever_yaw) * yaw_var
        cov[:2, 2] = cov[2, :2] = lever_yaw * yaw_var
        cov[2, 2] = yaw_var
        return Alignment(stamp, np.array([xy[0], xy[1], yaw]), cov, HEADING_FROM_COURSE, ground_velocity=latest.ground_velocity)

    def _fit(self) -> Alignment | None:
        gps = np.array([f.xy for f in self._samples])
        if len(self._samples) < self.min_fixes or np.linalg.norm(gps[-1] - gps[0]) < self.baseline_m:
            return None
        with_odo = [f for f in self._samples if f.antenna_odo is not None]
        sigma2 = float(np.mean([f.var for f in self._samples]))
        if len(with_odo) >= self.min_fixes:
            g = np.array([f.xy for f in with_odo])
            q = np.array([f.antenna_odo for f in with_odo])
            if np.linalg.norm(g[-1] - g[0]) < self.baseline_m:
                return None  # the odometry chain restarted recently: wait for it to span the baseline
            if np.linalg.norm(q[-1] - q[0]) >= 0.5 * self.baseline_m:
                # the fit places the latest fix's odometry pose; a latest fix without odometry has none to place
                odo = self._odo_at_last
                return self._procrustes(g, q, sigma2, odo) if odo is not None else None
        return self._course(gps, sigma2)

    def _procrustes(self, g: np.ndarray, q: np.ndarray, sigma2: float, odo: np.ndarray) -> Alignment:
        """Alignment placing `odo`, the odometry pose at the latest fix, from the fit of the odometry antenna track q onto the fixes g."""
        gc, qc = g - g.mean(0), q - q.mean(0)
        h = qc.T @ gc
        theta = float(np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1]))
        t = g.mean(0) - rot2(theta) @ q.mean(0)
        world = compose(np.array([t[0], t[1], theta]), odo)
        spread = float(np.sum(qc**2))
        residual = g - (q @ rot2(theta).T + t)
        sigma2 = max(sigma2, float(np.sum(residual**2)) / max(2 * (len(g) - 2), 1))  # per axis
        yaw_var = sigma2 / max(spread, 1e-9)
        cov = np.diag([sigma2, sigma2, yaw_var])
        return Alignment(self._samples[-1].stamp, world, cov, ground_velocity=self._samples[-1].ground_velocity)

    def _course(self, gps: np.ndarray, sigma2: float) -> Alignment:
        """Heading from the GPS course over the most recent travel long enough for the heading
        threshold (a shorter chord follows a turning boat better)."""
        need = 2.0 * sigma2 / self.max_yaw_var
        start = 0
        for k in range(len(gps) - 2, -1, -1):
            if float(np.sum((gps[-1] - gps[k]) ** 2)) >= need:
                start = k
                break
        gps = gps[start:]
        d = gps[-1] - gps[0]
        if len(gps) > 2:  # scatter about the straight line between the ends
            u = d / max(float(np.linalg.norm(d)), 1e-9)
            across = (gps - gps[0]) @ np.array([-u[1], u[0]])
            sigma2 = max(sigma2, float(np.var(across)))
        yaw = float(wrap_angle(np.arctan2(d[1], d[0])))
        xy = gps[-1] - rot2(yaw) @ self.lever
        yaw_var = 2.0 * sigma2 / max(float(d @ d), 1e-9)
        pose, cov = np.array([xy[0], xy[1], yaw]), np.diag([sigma2, sigma2, yaw_var])
        return Alignment(self._samples[-1].stamp, pose, cov, ground_velocity=self._samples[-1].ground_velocity)
