"""Start-up alignment: the odometry frame's rotation and offset in the world from the first GPS travel."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fusion.geometry import compose, rot2, wrap
from fusion.observation import FixObservation
from fusion.odometry import OdometryTrack


@dataclass(frozen=True)
class Alignment:
    """World pose of base_link at `stamp` and its 3x3 covariance, from a fit of odometry to GPS."""

    stamp: float
    pose: np.ndarray
    cov: np.ndarray


class Bootstrap:
    """Collects fixes until they span `baseline_m`, then fits rotation+translation of the odometry
    track onto them (2-D Procrustes). Without odometry spanning the travel, the heading is the GPS course (the boat moving forward).
    Only the last `window_s` of fixes are kept."""

    def __init__(self, baseline_m: float, min_fixes: int, max_hdop: float, lever: np.ndarray,
                 max_yaw_sd_deg: float = 5.0, window_s: float = 120.0) -> None:
        self.window_s = window_s
        self.max_yaw_var = np.radians(max_yaw_sd_deg) ** 2
        self.baseline_m = baseline_m
        self.min_fixes = min_fixes
        self.max_hdop = max_hdop
        self.lever = lever
        self._fixes: list[tuple[FixObservation, np.ndarray | None, int | None]] = []  # fix, odometry pose, segment

    def add(self, obs: FixObservation, odometry: OdometryTrack) -> Alignment | None:
        """Take one fix; return the alignment once there is enough travel for a heading within
        max_yaw_sd_deg (judged from the fit's own residuals, so noisy fixes need more travel)."""
        if obs.hdop > self.max_hdop:
            return None
        alignment = self._add(obs, odometry)
        if alignment is None or alignment.cov[2, 2] > self.max_yaw_var:
            return None
        return alignment

    def _add(self, obs: FixObservation, odometry: OdometryTrack) -> Alignment | None:
        odo = odometry.pose_at(obs.stamp) if odometry.velocity() is not None else None
        segment = odometry.segment if odo is not None else None
        if segment is not None:  # fixes seen on an earlier (broken) chain no longer link to this one
            self._fixes = [f if f[2] in (None, segment) else (f[0], None, None) for f in self._fixes]
        self._fixes.append((obs, odo, segment))
        self._fixes = [f for f in self._fixes if f[0].stamp >= obs.stamp - self.window_s]
        gps = np.array([f[0].xy for f in self._fixes])
        if len(self._fixes) < self.min_fixes or np.linalg.norm(gps[-1] - gps[0]) < self.baseline_m:
            return None
        with_odo = [(f[0], f[1]) for f in self._fixes if f[1] is not None]
        sigma2 = float(np.mean([np.trace(f[0].cov) / 2.0 for f in self._fixes]))
        if len(with_odo) >= self.min_fixes:
            g = np.array([o.xy for o, _ in with_odo])
            q = np.array([p[:2] for _, p in with_odo])
            if np.linalg.norm(g[-1] - g[0]) < self.baseline_m:
                return None  # the odometry chain restarted recently: wait for it to span the baseline
            if np.linalg.norm(q[-1] - q[0]) >= 0.5 * self.baseline_m:
                return self._procrustes(with_odo, sigma2)
        return self._course(gps, sigma2)

    def _procrustes(self, pairs: list[tuple[FixObservation, np.ndarray]], sigma2: float) -> Alignment:
        g = np.array([o.xy for o, _ in pairs])
        q = np.array([p[:2] + rot2(p[2]) @ self.lever for _, p in pairs])
        gc, qc = g - g.mean(0), q - q.mean(0)
        h = qc.T @ gc
        theta = float(np.arctan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1]))
        t = g.mean(0) - rot2(theta) @ q.mean(0)
        last_obs, last_odo = pairs[-1]
        world = compose(np.array([t[0], t[1], theta]), last_odo)
        spread = float(np.sum(qc**2))
        residual = g - (q @ rot2(theta).T + t)
        sigma2 = max(sigma2, float(np.sum(residual**2)) / max(2 * (len(g) - 2), 1))  # per axis
        yaw_var = sigma2 / max(spread, 1e-9)
        cov = np.diag([sigma2, sigma2, yaw_var])
        return Alignment(last_obs.stamp, world, cov)

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
        yaw = float(wrap(np.arctan2(d[1], d[0])))
        xy = gps[-1] - rot2(yaw) @ self.lever
        yaw_var = 2.0 * sigma2 / max(float(d @ d), 1e-9)
        return Alignment(self._fixes[-1][0].stamp, np.array([xy[0], xy[1], yaw]), np.diag([sigma2, sigma2, yaw_var]))
