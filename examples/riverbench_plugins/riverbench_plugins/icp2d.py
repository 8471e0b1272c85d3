"""Icp2d: point-to-line ICP of the scan's walls projected onto the x-y plane (a riverbench matcher plugin).

The protocol: a class with a pydantic `Params` model, built as `Icp2d(params)`, whose
`register(scan)` returns a `matcher.MatchResult` for every scan: `T` is this scan's lidar frame in
the reference scan's (the previous one that passed the gate), `info["ref_stamp"]` names that scan.
A scan that passes the gate becomes the next reference even when its match fails; a gated one
(`info["gated"]`) never does.
"""

from __future__ import annotations

import math
import time

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.spatial import cKDTree

from matcher import MatchResult
from sim.scan import Scan


class Icp2dParams(BaseModel):
    """Icp2d's parameters (defaults in brackets)."""

    model_config = ConfigDict(extra="forbid")
    min_range_m: float = Field(2.0, ge=0.0, description="ignore returns closer than this (the boat itself) [2 m]")
    max_range_m: float = Field(60.0, gt=0.0, description="ignore returns farther than this [60 m]")
    min_z_m: float = Field(-1.0, description="lowest point kept, lidar frame: drops the water, 1.8 m below the lidar [-1 m]")
    max_z_m: float = Field(10.0, description="highest point kept, lidar frame [10 m]")
    cell_m: float = Field(0.3, gt=0.0, description="grid cell of the x-y projection: one point (the mean) per wall cell [0.3 m]")
    min_height_m: float = Field(0.2, ge=0.0, description="a cell is a wall's when its points span this much height [0.2 m]")
    min_points: int = Field(100, ge=10, description="a scan with fewer projected points is gated: not matched, never the reference [100]")
    neighbours: int = Field(6, ge=3, description="reference points fitted with a line for each normal [6]")
    max_correspondence_m: float = Field(1.0, gt=0.0, description="farther pairs are not used [1 m]")
    huber_m: float = Field(0.1, gt=0.0, description="residuals beyond this are down-weighted [0.1 m]")
    max_iterations: int = Field(30, ge=1, description="Gauss-Newton steps at most [30]")
    min_overlap: float = Field(0.5, gt=0.0, le=1.0, description="a smaller share of points with a partner fails the match [0.5]")
    max_speed_mps: float = Field(10.0, gt=0.0, description="faster estimated motion fails the match [10 m/s]")
    degenerate_ratio: float = Field(
        0.01, gt=0.0, lt=1.0, description="a translation direction with less than this share of the strongest one's information is degenerate [0.01]"
    )
    degenerate_sigma_m: float = Field(1.0, gt=0.0, description="sigma reported along a degenerate direction, per scan [1 m]")


class Icp2d:
    """Scan-to-previous-scan 2-D ICP (x, y, yaw), de-skewed and started from the constant-velocity motion of the last match."""

    Params = Icp2dParams

    def __init__(self, params: Icp2dParams) -> None:
        self.params = params
        self._ref: tuple[float, np.ndarray, np.ndarray, cKDTree] | None = None  # stamp, points, normals, tree
        self._rate: np.ndarray | None = None  # (dx, dy, dyaw) per second of the last good match

    def register(self, scan: Scan) -> MatchResult:
        """This scan's motion against the reference scan (ok=False with info['reason'] when it fails)."""
        start = time.perf_counter()
        result = self._register(scan)
        result.seconds = time.perf_counter() - start
        return result

    def _register(self, scan: Scan) -> MatchResult:
        """The match itself; `register` times it."""
        xy = self._project(scan)
        if len(xy) < self.params.min_points:
            return MatchResult.failure(f"{len(xy)} projected points < min_points {self.params.min_points}", n_points=len(xy), gated=True)
        if self._ref is None:
            self._set_reference(scan.stamp, xy)
            return MatchResult.failure("first scan", n_points=len(xy))
        ref_stamp = self._ref[0]
        dt = scan.stamp - ref_stamp
        if not dt > 0.0:
            return MatchResult.failure(f"stamp {scan.stamp} not after the reference's {ref_stamp}", n_points=len(xy), gated=True)
        guess = self._rate * dt if self._rate is not None else np.zeros(3)
        x, info, reason = self._align(xy, guess)
        info["ref_stamp"] = ref_stamp
        if not reason and math.hypot(x[0], x[1]) / dt > self.params.max_speed_mps:
            reason = f"implausible speed {math.hypot(x[0], x[1]) / dt:.1f} m/s"
        self._rate = None if reason else x / dt
        self._set_reference(scan.stamp, self._project(scan))  # de-skewed as the next scan will be: with the new rate
        if reason:
            return MatchResult.failure(reason, n_points=len(xy), **info)
        return MatchResult(T=_pose(x), ok=True, cov=info.pop("cov"), n_points=len(xy), seconds=0.0, info=info)

    def _project(self, scan: Scan) -> np.ndarray:
        """The scan's wall points projected on x-y: the mean point of each grid cell whose points span
        min_height_m or more (a vertical surface; a horizontal one, such as a deck's underside, would
        draw rings that move with the boat)."""
        p = self.params
        pts = scan.points
        xyz = np.stack([pts["x"], pts["y"], pts["z"]], axis=1).astype(np.float64)
        rng = np.linalg.norm(xyz, axis=1)
        keep = np.isfinite(rng) & (rng >= p.min_range_m) & (rng <= p.max_range_m) & (xyz[:, 2] >= p.min_z_m) & (xyz[:, 2] <= p.max_z_m)
        xy = _deskew(xyz[keep, :2], pts["time"][keep].astype(np.float64), self._rate)
        z = xyz[keep, 2]
        if len(xy) == 0:
            return xy
        _, cell, count = np.unique(np.floor(xy / p.cell_m).astype(np.int64), axis=0, return_inverse=True, return_counts=True)
        cell = cell.reshape(-1)
        low, high = np.full(len(count), np.inf), np.full(len(count), -np.inf)
        np.minimum.at(low, cell, z)
        np.maximum.at(high, cell, z)
        mean = np.stack([np.bincount(cell, xy[:, 0]), np.bincount(cell, xy[:, 1])], axis=1) / count[:, None]
        return mean[high - low >= p.min_height_m]

    def _set_reference(self, stamp: float, xy: np.ndarray) -> None:
        """Make `xy` the reference: its k-d tree and each point's normal (the line through its neighbours)."""
        tree = cKDTree(xy)
        _, idx = tree.query(xy, k=min(self.params.neighbours, len(xy)))
        local = xy[idx] - xy[idx].mean(axis=1, keepdims=True)
        _, vectors = np.linalg.eigh(np.einsum("nki,nkj->nij", local, local))
        self._ref = (stamp, xy, vectors[:, :, 0], tree)

    def _align(self, xy: np.ndarray, guess: np.ndarray) -> tuple[np.ndarray, dict, str]:
        """(dx, dy, dyaw) taking `xy` onto the reference from `guess`, diagnostics with the 6x6 'cov', and a failure reason or ''."""
        p = self.params
        _, ref, normals, tree = self._ref
        x = guess.astype(float).copy()
        for iteration in range(1, p.max_iterations + 1):
            J, r, w, overlap = self._linearise(xy, x, ref, normals, tree)
            if overlap < p.min_overlap:
                return x, {"overlap": overlap, "iterations": iteration}, f"overlap {overlap:.2f} < min_overlap {p.min_overlap}"
            H = J.T @ (w[:, None] * J)
            step = -np.linalg.solve(H + 1e-9 * np.trace(H) * np.eye(3), J.T @ (w * r))
            x += step
            if np.hypot(step[0], step[1]) < 1e-4 and abs(step[2]) < 1e-5:
                break
        sigma2 = float(np.sum(w * r**2) / max(w.sum() - 3.0, 1.0))
        cov3, degenerate = self._covariance(H, sigma2)
        cov = np.diag([0.0, 0.0, 1.0, 0.01, 0.01, 0.0])  # z, roll, pitch: not observed in the plane
        cov[np.ix_([0, 1, 5], [0, 1, 5])] = cov3
        return x, {"cov": cov, "overlap": overlap, "iterations": iteration, "rmse": math.sqrt(sigma2), "degenerate": degenerate}, ""

    def _linearise(
        self, xy: np.ndarray, x: np.ndarray, ref: np.ndarray, normals: np.ndarray, tree: cKDTree
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """Point-to-line residuals at `x`, their Jacobian, Huber weights and the share of points paired."""
        c, s = math.cos(x[2]), math.sin(x[2])
        rotated = xy @ np.array([[c, s], [-s, c]])
        dist, idx = tree.query(rotated + x[:2], distance_upper_bound=self.params.max_correspondence_m)
        paired = np.isfinite(dist)
        n, q = normals[idx[paired]], ref[idx[paired]]
        moved = rotated[paired]
        r = np.einsum("ni,ni->n", n, moved + x[:2] - q)
        J = np.column_stack([n, n[:, 0] * -moved[:, 1] + n[:, 1] * moved[:, 0]])
        w = np.minimum(1.0, self.params.huber_m / np.maximum(np.abs(r), 1e-12))
        return J, r, w, float(paired.mean())

    def _covariance(self, H: np.ndarray, sigma2: float) -> tuple[np.ndarray, bool]:
        """sigma^2 H^-1, with degenerate_sigma_m along a translation direction the walls leave unobserved."""
        cov = sigma2 * np.linalg.inv(H + 1e-9 * np.trace(H) * np.eye(3))
        values, vectors = np.linalg.eigh(H[:2, :2])
        degenerate = bool(values[0] < self.params.degenerate_ratio * values[1])
        if degenerate:
            u = vectors[:, 0]
            cov[:2, :2] += self.params.degenerate_sigma_m**2 * np.outer(u, u)
        return 0.5 * (cov + cov.T), degenerate


def _deskew(xy: np.ndarray, t: np.ndarray, rate: np.ndarray | None) -> np.ndarray:
    """Points fired t s into the revolution moved into the lidar frame at its start, by the motion `rate` (None: as they are)."""
    if rate is None:
        return xy
    angle = rate[2] * t
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * xy[:, 0] - s * xy[:, 1] + rate[0] * t, s * xy[:, 0] + c * xy[:, 1] + rate[1] * t], axis=1)


def _pose(x: np.ndarray) -> np.ndarray:
    """4x4 pose of a planar motion (dx, dy, dyaw)."""
    T = np.eye(4)
    c, s = math.cos(x[2]), math.sin(x[2])
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = x[:2]
    return T
