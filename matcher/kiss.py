"""kiss_icp: the kiss-icp package's own odometry pipeline behind the Matcher interface."""

from __future__ import annotations

from typing import Any

import numpy as np
from kiss_icp.config import KISSConfig
from kiss_icp.kiss_icp import KissICP
from pydantic import Field
from scipy.spatial import cKDTree

from matcher.base import Matcher, MatcherParams
from matcher.cloud import Cloud
from matcher.motion import se3_exp, se3_log, transform
from matcher.result import MatchResult


class KissIcpParams(MatcherParams):
    """Settings of the `kiss_icp` matcher (passed to kiss-icp's KISSConfig)."""

    voxel_m: float = Field(
        0.5, gt=0.0, description="kiss-icp mapping.voxel_size (default 0.5 m; kiss-icp's max_range/100 = 1 m sticks on smooth canal walls)"
    )
    max_points_per_voxel: int = Field(20, ge=1, description="kiss-icp mapping.max_points_per_voxel (default 20)")
    deskew: bool = Field(True, description="kiss-icp data.deskew from the per-point time field (default on)")
    max_iterations: int = Field(500, ge=1, description="kiss-icp registration.max_num_iterations (default 500)")
    convergence: float = Field(1e-4, gt=0.0, description="kiss-icp registration.convergence_criterion (default 1e-4)")
    num_threads: int = Field(1, ge=0, description="kiss-icp registration.max_num_threads (0 = all; default 1, steadiest on a shared machine)")
    min_overlap: float = Field(
        0.8, ge=0.0, le=1.0, description="fail when a smaller share of registered points lies within 3 voxels of the previous scan's (default 0.8)"
    )


class KissIcp(Matcher):
    """kiss_icp.kiss_icp.KissICP (scan-to-local-map, adaptive threshold, constant-velocity deskew).

    kiss-icp expresses each scan at its last point's time (it de-skews to the end of the
    revolution with the previous relative motion); poses are moved back to each scan's stamp."""

    name = "kiss_icp"

    def __init__(self, params: KissIcpParams) -> None:
        super().__init__(params)
        self.p = params
        self._reset()

    def _config(self) -> KISSConfig:
        p = self.p
        cfg = KISSConfig()
        cfg.data.max_range, cfg.data.min_range, cfg.data.deskew = p.max_range_m, p.min_range_m, p.deskew
        cfg.mapping.voxel_size, cfg.mapping.max_points_per_voxel = p.voxel_m, p.max_points_per_voxel
        cfg.registration.max_num_iterations = p.max_iterations
        cfg.registration.convergence_criterion = p.convergence
        cfg.registration.max_num_threads = p.num_threads
        return cfg

    def _reset(self) -> None:
        self._kiss: KissICP | None = None
        self._period: float | None = None
        self._ref_pose: np.ndarray | None = None  # kiss map <- reference scan's lidar frame at its stamp
        self._ref_tree: cKDTree | None = None
        self._pending: tuple[np.ndarray, cKDTree, Cloud] | None = None

    def _run(self, cloud: Cloud) -> tuple[np.ndarray, np.ndarray]:
        """Register with kiss-icp: (map <- lidar frame at the stamp, the points it used, in the map)."""
        kiss = self._kiss
        assert kiss is not None  # _start creates it
        delta = kiss.last_delta
        _, source = kiss.register_frame(cloud.xyz, cloud.time)
        pose_end = kiss.last_pose
        in_map = transform(source, pose_end[:3, :3], pose_end[:3, 3])
        if not self.p.deskew or len(cloud.time) < 2 or np.ptp(cloud.time) <= 0:
            return pose_end, in_map
        # kiss-icp: a point at normalised time s = (t - tmin) / (tmax - tmin) is at pose_end exp((s - 1) log delta)
        s0 = -cloud.time.min() / np.ptp(cloud.time)
        return pose_end @ se3_exp((s0 - 1.0) * se3_log(delta)), in_map

    def _start(self, cloud: Cloud) -> None:
        self._kiss = KissICP(self._config())
        if self.velocity.twist_per_s is not None and self._period is not None:  # a restart keeps the vessel's motion
            self._kiss.last_delta = se3_exp(self.velocity.twist_per_s * self._period)
        pose, source = self._run(cloud)
        self._ref_pose, self._ref_tree = pose, cKDTree(source)

    def _commit(self, ok: bool) -> None:
        pending = self._pending
        assert pending is not None  # _match leaves its registration here
        pose, tree, cloud = pending
        self._pending = None
        if ok:
            self._ref_pose, self._ref_tree = pose, tree
        else:  # kiss-icp has mapped this scan at a wrong pose: restart it from this scan
            self._start(cloud)

    def _match(self, cloud: Cloud, dt: float) -> MatchResult:
        kiss, ref_pose, ref_tree = self._kiss, self._ref_pose, self._ref_tree
        assert kiss is not None and ref_pose is not None and ref_tree is not None  # _start sets them
        self._period = dt if self._period is None else min(self._period, dt)
        gap = dt / self._period
        if gap > 1.5:  # scans were dropped: advance kiss-icp's pose over them at constant velocity
            kiss.last_pose = kiss.last_pose @ se3_exp((gap - 1.0) * se3_log(kiss.last_delta))
        pose, source = self._run(cloud)
        T = np.linalg.inv(ref_pose) @ pose
        dist, _ = ref_tree.query(source, distance_upper_bound=3.0 * self.p.voxel_m)
        overlap = float(np.isfinite(dist).mean()) if len(source) else 0.0
        self._pending = (pose, cKDTree(source), cloud)
        info: dict[str, Any] = {
            "overlap": overlap,
            "points_used": int(len(source)),
            "adaptive_threshold": float(kiss.adaptive_threshold.get_threshold()),
        }
        if overlap < self.p.min_overlap:
            return MatchResult.failure(f"overlap {overlap:.2f} < min_overlap {self.p.min_overlap}", **info)
        return MatchResult(T=T, ok=True, cov=None, n_points=0, seconds=0.0, info=info)
