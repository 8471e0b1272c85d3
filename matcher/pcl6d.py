"""pcl6d: the field study's Method 1, a PCL-style 6-DoF pipeline on Open3D.

Voxel filter, statistical outlier removal, normals; FPFH features with mutual-nearest-neighbour
correspondences and RANSAC pre-alignment (edge-length and distance checkers; FGR as an option);
point-to-plane ICP with Tukey's robust kernel (Open3D's generalized ICP as an option)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import Literal

import numpy as np
import open3d as o3d
from pydantic import Field
from scipy.spatial import cKDTree

from matcher.base import DeskewingMatcher, MatcherParams
from matcher.cloud import Cloud
from matcher.covariance import DegeneracyParams, FloorParams, covariance_from_hessian, left_perturbation_jacobian, to_xyzrpy
from matcher.deskew import deskew_rounds
from matcher.motion import deskew, planar, transform
from matcher.pointplane import point_to_plane_fit
from matcher.result import MatchResult
from sim.scan import Scan

reg = o3d.pipelines.registration


@contextmanager
def one_thread() -> Iterator[None]:
    """Open3D on one thread inside the block, its thread count restored after. On two threads or more a registration is
    not repeatable: Open3D's RANSAC draws every thread's samples from one seeded generator, so the order of the draws,
    and with the correspondence checkers the answer, follows the OS scheduler (isl-org/Open3D#7475, a maintainer's
    reply: only one thread makes it repeatable), and its ICP sums each thread's share of the normal equations in the
    order the threads finish, so the last bits of every step differ (measured: 15 repeats of one six-scan sequence on
    two threads gave 15 different answers). PCL's SampleConsensusPrerejective and ICP, which Method 1 stands for, are
    serial loops."""
    threads = o3d.utility.get_max_threads()
    o3d.utility.set_max_threads(1)
    try:
        yield
    finally:
        o3d.utility.set_max_threads(threads)


class Pcl6dParams(MatcherParams, DegeneracyParams, FloorParams):
    """Settings of the `pcl6d` matcher."""

    voxel_m: float = Field(0.4, gt=0.0, description="voxel filter leaf size for ICP (default 0.4 m)")
    sor_neighbors: int = Field(16, ge=2, description="statistical outlier removal: neighbours (default 16)")
    sor_std_ratio: float = Field(2.5, gt=0.0, description="statistical outlier removal: std. dev. multiplier (default 2.5)")
    normal_radius_m: float = Field(
        3.0,
        gt=0.0,
        description="normal estimation radius (default 3 m): wider than the HDL-32E's ring spacing at its 100 m range "
        "(lasers 1.33 deg apart, user's manual: 100 m x tan 1.33 deg = 2.3 m), so that every normal is fitted to two rings, "
        "not to one ring's line, whose least-spread direction (across the range noise) points up; see docs/models.md",
    )
    normal_max_nn: int = Field(
        30,
        ge=3,
        description="normal estimation max neighbours (default 30): at 0.4 m voxels one ring gives about 15 points within "
        "normal_radius_m, the next ring the rest",
    )
    prealign: Literal["ransac", "fgr", "none"] = Field("ransac", description="global pre-alignment method (default ransac)")
    prealign_voxel_m: float = Field(1.0, gt=0.0, description="voxel size of the FPFH pre-alignment clouds (default 1 m)")
    fpfh_radius_m: float = Field(5.0, gt=0.0, description="FPFH feature radius (default 5 m)")
    fpfh_max_nn: int = Field(100, ge=5, description="FPFH max neighbours (default 100)")
    mutual_filter: bool = Field(True, description="keep only mutual nearest-neighbour feature matches (default on)")
    ransac_distance_m: float = Field(1.5, gt=0.0, description="RANSAC inlier distance and distance checker (default 1.5 m)")
    edge_length_similarity: float = Field(0.9, gt=0.0, lt=1.0, description="edge-length checker similarity (default 0.9)")
    ransac_max_iterations: int = Field(50000, ge=1, description="RANSAC iterations (default 50000)")
    ransac_confidence: float = Field(0.999, gt=0.0, lt=1.0, description="RANSAC confidence (default 0.999)")
    ransac_until: Literal["confidence", "max_iterations"] = Field(
        "confidence",
        description="when RANSAC stops: 'confidence' (default) once ransac_confidence is reached (Open3D's adaptive count); "
        "'max_iterations' after exactly ransac_max_iterations hypotheses, as PCL's SampleConsensusPrerejective does (its "
        "computeTransformation loop has no early exit: registration/impl/sample_consensus_prerejective.hpp)",
    )
    ransac_seed: int = Field(
        0, ge=0, description="seed of Open3D's RANSAC sampler, set before each pre-alignment (on one thread: repeatable runs; default 0)"
    )
    planar_initial_guess: bool = Field(True, description="keep only x, y, yaw of the pre-alignment as ICP's start (boats stay level; default on)")
    skip_prealign_max_dt_s: float = Field(
        0.25,
        ge=0.0,
        description="skip pre-alignment (start ICP from the motion prior, or identity) when scans are at most this far apart (default 0.25 s)",
    )
    skip_icp_min_fitness: float | None = Field(
        None, gt=0.0, le=1.0, description="skip ICP when pre-alignment inlier share reaches this (and RMSE limit holds); None = always run ICP"
    )
    skip_icp_max_rmse_m: float = Field(0.1, gt=0.0, description="pre-alignment inlier RMSE limit for skipping ICP (default 0.1 m)")
    icp: Literal["point_to_plane", "gicp"] = Field("point_to_plane", description="fine alignment (default point_to_plane)")
    icp_max_correspondence_m: float = Field(1.0, gt=0.0, description="ICP max pair distance (default 1 m)")
    tukey_k_m: float = Field(0.15, gt=0.0, description="Tukey robust-kernel width; larger residuals are outliers (default 0.15 m)")
    gicp_tukey_k: float = Field(1.0, gt=0.0, description="Tukey width for icp='gicp', on its Mahalanobis-weighted residual (default 1)")
    icp_max_iterations: int = Field(30, ge=1, description="ICP iterations (default 30)")
    deskew_iterations: int = Field(2, ge=1, description="de-skew/register rounds; later rounds de-skew with the new estimate (default 2)")
    min_fitness: float = Field(
        0.8, ge=0.0, le=1.0, description="fail when a smaller share of points finds a partner within icp_max_correspondence_m (default 0.8)"
    )
    max_outlier_share: float = Field(0.2, ge=0.0, le=1.0, description="fail when a larger share of partners lies beyond tukey_k_m (default 0.2)")


class _Prepared:
    """A de-skewed, filtered scan with normals; FPFH features on demand."""

    def __init__(self, cloud: Cloud, twist: np.ndarray | None, p: Pcl6dParams) -> None:
        self.cloud, self.twist, self.p = cloud, twist, p
        self.xyz_deskewed = deskew(cloud.xyz, cloud.time, twist)
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(self.xyz_deskewed)).voxel_down_sample(p.voxel_m)
        if len(pcd.points) > p.sor_neighbors:
            pcd, _ = pcd.remove_statistical_outlier(p.sor_neighbors, p.sor_std_ratio)
        pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=p.normal_radius_m, max_nn=p.normal_max_nn))
        pcd.orient_normals_towards_camera_location(np.zeros(3))
        self.pcd = pcd
        self.points = np.asarray(pcd.points)
        self.normals = np.asarray(pcd.normals)
        self.tree = cKDTree(self.points)
        self._features: tuple[o3d.geometry.PointCloud, np.ndarray] | None = None

    def features(self) -> tuple[o3d.geometry.PointCloud, np.ndarray]:
        """Coarse cloud for pre-alignment and its FPFH descriptors (N, 33)."""
        if self._features is None:
            p = self.p
            coarse = self.pcd.voxel_down_sample(p.prealign_voxel_m)
            coarse.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=2.0 * p.prealign_voxel_m, max_nn=30))
            fpfh = reg.compute_fpfh_feature(coarse, o3d.geometry.KDTreeSearchParamHybrid(radius=p.fpfh_radius_m, max_nn=p.fpfh_max_nn))
            self._features = (coarse, np.asarray(fpfh.data).T.copy())
        return self._features


class Pcl6d(DeskewingMatcher[_Prepared]):
    """Method 1: filter, FPFH + RANSAC pre-alignment, robust point-to-plane ICP."""

    name = "pcl6d"

    def __init__(self, params: Pcl6dParams) -> None:
        super().__init__(params)
        self.p = params

    def _register(self, scan: Scan) -> MatchResult:
        with one_thread():  # repeatable: every Open3D step of a registration on one thread (one_thread)
            return super()._register(scan)

    def _prepare(self, cloud: Cloud, twist: np.ndarray | None) -> _Prepared:
        return _Prepared(cloud, twist, self.p)

    def _prealign(self, src: _Prepared, tgt: _Prepared) -> tuple[np.ndarray, dict]:
        """Global alignment from FPFH correspondences; (T, diagnostics)."""
        p = self.p
        src_pcd, src_f = src.features()
        tgt_pcd, tgt_f = tgt.features()
        if len(src_f) < 3 or len(tgt_f) < 3:
            return np.eye(4), {"prealign_putative": 0, "prealign_rejected_share": 1.0, "prealign_fitness": 0.0, "prealign_rmse": float("inf")}
        _, to_tgt = cKDTree(tgt_f).query(src_f)
        pairs = np.stack([np.arange(len(src_f)), to_tgt], axis=1)
        if p.mutual_filter:
            _, to_src = cKDTree(src_f).query(tgt_f)
            pairs = pairs[to_src[to_tgt] == np.arange(len(src_f))]
        corres = o3d.utility.Vector2iVector(pairs.astype(np.int32))
        if p.prealign == "fgr":
            res = reg.registration_fgr_based_on_correspondence(
                src_pcd, tgt_pcd, corres, reg.FastGlobalRegistrationOption(maximum_correspondence_distance=p.ransac_distance_m)
            )
            res = reg.evaluate_registration(src_pcd, tgt_pcd, p.ransac_distance_m, res.transformation)
        else:
            checkers = [
                reg.CorrespondenceCheckerBasedOnEdgeLength(p.edge_length_similarity),
                reg.CorrespondenceCheckerBasedOnDistance(p.ransac_distance_m),
            ]
            o3d.utility.random.seed(p.ransac_seed)
            res = reg.registration_ransac_based_on_correspondence(
                src_pcd,
                tgt_pcd,
                corres,
                p.ransac_distance_m,
                reg.TransformationEstimationPointToPoint(False),
                3,
                checkers,
                reg.RANSACConvergenceCriteria(p.ransac_max_iterations, 1.0 if p.ransac_until == "max_iterations" else p.ransac_confidence),
            )
        T = np.asarray(res.transformation)
        # feature correspondences the final transform rejects (the field study's outlier share)
        src_xyz, tgt_xyz = np.asarray(src_pcd.points)[pairs[:, 0]], np.asarray(tgt_pcd.points)[pairs[:, 1]]
        residual = np.linalg.norm(transform(src_xyz, T[:3, :3], T[:3, 3]) - tgt_xyz, axis=1)
        rejected = float((residual > p.ransac_distance_m).mean()) if len(pairs) else 1.0
        info = {
            "prealign_putative": int(len(pairs)),
            "prealign_rejected_share": rejected,
            "prealign_fitness": float(res.fitness),
            "prealign_rmse": float(res.inlier_rmse),
        }
        return T, info

    def _icp(self, src: _Prepared, tgt: _Prepared, init: np.ndarray) -> np.ndarray:
        p = self.p
        criteria = reg.ICPConvergenceCriteria(1e-6, 1e-6, p.icp_max_iterations)
        if p.icp == "gicp":
            est = reg.TransformationEstimationForGeneralizedICP(reg.TukeyLoss(k=p.gicp_tukey_k))
            res = reg.registration_generalized_icp(src.pcd, tgt.pcd, p.icp_max_correspondence_m, init, est, criteria)
        else:
            est = reg.TransformationEstimationPointToPlane(reg.TukeyLoss(k=p.tukey_k_m))
            res = reg.registration_icp(src.pcd, tgt.pcd, p.icp_max_correspondence_m, init, est, criteria)
        return np.asarray(res.transformation)

    def _align(self, src: _Prepared, tgt: _Prepared, prior: np.ndarray | None, dt: float, first_round: dict | None = None) -> tuple[np.ndarray, dict]:
        """ICP from the motion prior when scans are close in time (identity without a prior: a boat
        moves little in a revolution); global pre-alignment first when they are not, or when that fails.
        A later de-skew round (first_round: the first round's diagnostics, which it reports on) starts from the previous
        round's answer as a prior: de-skewed again, the scan moves by centimetres, so a second global search would only
        repeat the first (the field study's Method 1 pre-aligns each pair once); a first round that kept the
        pre-alignment's answer without ICP (skip_icp_min_fitness) keeps it."""
        p = self.p
        if first_round is not None and first_round["icp_skipped"]:
            return prior if prior is not None else np.eye(4), dict(first_round)
        info: dict = {"prealigned": False, "icp_skipped": False} if first_round is None else {**first_round, "icp_skipped": False}
        if first_round is not None or dt <= p.skip_prealign_max_dt_s or p.prealign == "none":
            T = self._icp(src, tgt, np.eye(4) if prior is None else prior)
            fit = point_to_plane_fit(src.points, T, tgt.points, tgt.normals, tgt.tree, p.icp_max_correspondence_m, p.tukey_k_m)
            if fit.fitness >= p.min_fitness or p.prealign == "none":
                return T, info
            info["prior_failed"] = True  # ICP from the prior went astray: fall back to global pre-alignment
        T0, pre = self._prealign(src, tgt)
        info.update(pre, prealigned=True)
        init = planar(T0) if p.planar_initial_guess else T0
        if p.skip_icp_min_fitness is not None and pre["prealign_fitness"] >= p.skip_icp_min_fitness and pre["prealign_rmse"] <= p.skip_icp_max_rmse_m:
            info["icp_skipped"] = True
            return T0, info
        return self._icp(src, tgt, init), info

    def _match(self, cloud: Cloud, dt: float) -> MatchResult:
        p = self.p
        twist = self.velocity.twist_per_s

        first_round: dict | None = None

        def align(cur: _Prepared, ref: _Prepared, T: np.ndarray | None) -> tuple[np.ndarray, dict] | None:
            nonlocal first_round
            if len(cur.points) < 10 or len(ref.points) < 10:
                return None
            aligned = self._align(cur, ref, T, dt, first_round)
            first_round = aligned[1] if first_round is None else first_round
            return aligned

        ref, cur, aligned = deskew_rounds(
            cloud,
            self._reference(),
            twist,
            None if twist is None else self.velocity.predict(dt),
            dt,
            p.deskew_iterations,
            self._prepare,
            align,
        )
        self._cur = cur
        if aligned is None:
            return MatchResult.failure("too few points after filtering")
        self._ref = ref
        T, info = aligned
        fit = point_to_plane_fit(cur.points, T, ref.points, ref.normals, ref.tree, p.icp_max_correspondence_m, p.tukey_k_m)
        info.update(fitness=fit.fitness, outlier_share=fit.outlier_share, points_used=len(cur.points), sigma2=fit.sigma2)
        if fit.fitness < p.min_fitness:
            return MatchResult.failure(f"fitness {fit.fitness:.2f} < min_fitness {p.min_fitness}", **info)
        if fit.outlier_share > p.max_outlier_share:
            return MatchResult.failure(f"outlier share {fit.outlier_share:.2f} > max_outlier_share {p.max_outlier_share}", **info)
        cov_param, degeneracy = covariance_from_hessian(fit.H, fit.sigma2, p.degenerate_ratio, p.degenerate_sigma_m, p.degenerate_sigma_rad)
        cov = p.add_to(to_xyzrpy(cov_param, left_perturbation_jacobian(T)))
        info.update(degeneracy.as_info())
        return MatchResult(T=T, ok=True, cov=cov, n_points=0, seconds=0.0, info=info)
