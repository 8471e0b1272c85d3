"""gicp: small_gicp's Generalized-ICP on de-skewed scans, a fast 6-DoF reference: each scan is registered against a
keyframe (keyframe_m; 0: against the previous scan) and reported as the step from the previous good scan.

Its covariance and degeneracy come from the point-to-plane information of the solution, each
reference point's normal weighed by its planarity (matcher.planarity), not from GICP's own Hessian.
That Hessian counts every point with the normal small_gicp fitted to its 12 neighbours; where those
lie on one scan line (a deck overhead seen at a grazing angle, a far wall) the normal is free to
turn about the line, and such points fake information along the surface: the ring pattern the
sensor draws on it moves with the sensor, so they favour "no motion". Under charles_river's
Charlestown Bridge (a flat deck, piers at 10 deg to the route) GICP reported the boat stopped,
+-1 cm, while entering and leaving the deck. Along a translation the planes leave free, the motion
prior is kept (matcher.remap). Before the first good match, or after the prior expires, there is no
prior, only the identity: where the scans still measure the motion (between canal_lock's canyon walls
it is degenerate relative to the lateral information, yet measured to 2 cm) keeping it pinned the boat
at rest for as long as the walls ran, so there GICP's answer stands; where they measure nothing (open
water, no plane in range) GICP's answer is noise, and the identity stays. Degenerate rotations keep
GICP's estimate and only get the inflated covariance: they are judged against yaw's information,
which the lever arms of distant points make large, so a roll measured to 0.1 deg by a canal's walls
is flagged too, and a constant-rate prior in a chop is worse than that. Returns from a boat keeping station with the sensor (a chase boat)
are dropped before registering (matcher.comoving): taken as static, they pulled the motion towards
zero, to a quarter of the true one under the BU Bridge."""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cached_property
from typing import Any, Literal

import numpy as np
import small_gicp
from pydantic import Field

from matcher.base import DeskewingMatcher, MatcherParams
from matcher.cloud import Cloud
from matcher.comoving import moving_with_sensor
from matcher.covariance import (
    Degeneracy,
    DegeneracyParams,
    FloorParams,
    covariance_from_hessian,
    left_perturbation_jacobian,
    to_xyzrpy,
)
from matcher.deskew import deskew_rounds
from matcher.motion import adjoint, deskew, pose_to_xyzrpy, se3_exp
from matcher.movers import MoverTest, moving_objects
from matcher.planarity import planarity
from matcher.pointplane import PlaneFit, point_to_plane_fit
from matcher.remap import keep_prior_along
from matcher.result import MatchResult
from matcher.scene_grid import carried, downsample


class GicpParams(MatcherParams, DegeneracyParams, FloorParams):
    """Settings of the `gicp` matcher."""

    registration_type: Literal["GICP", "PLANE_ICP", "ICP"] = Field("GICP", description="small_gicp factor (default GICP)")
    voxel_m: float = Field(0.3, gt=0.0, description="voxel-grid downsampling resolution (default 0.3 m)")
    num_neighbors: int = Field(12, ge=5, description="neighbours for per-point covariance estimation (default 12)")
    max_correspondence_m: float = Field(1.0, gt=0.0, description="max point-pair distance (default 1 m)")
    max_iterations: int = Field(30, ge=1, description="optimiser iterations (default 30)")
    translation_epsilon_m: float = Field(1e-4, gt=0.0, description="convergence: translation update below this (default 0.1 mm)")
    rotation_epsilon_rad: float = Field(1e-5, gt=0.0, description="convergence: rotation update below this (default 1e-5 rad)")
    num_threads: int = Field(1, ge=1, description="threads for small_gicp (default 1: its OpenMP threads spin badly on a busy machine)")
    deskew_iterations: int = Field(2, ge=1, description="de-skew/register rounds; later rounds de-skew with the new estimate (default 2)")
    min_inlier_share: float = Field(
        0.8, ge=0.0, le=1.0, description="fail when a smaller share of points finds a partner within max_correspondence_m (default 0.8)"
    )
    tukey_k_m: float = Field(
        0.15, gt=0.0, description="Tukey width of the point-to-plane residuals that give the covariance and degeneracy (default 0.15 m)"
    )
    planarity_voxel_m: float = Field(
        1.0, gt=0.0, description="voxel in which a point's planarity is measured (default 1 m: about its normal's neighbours)"
    )
    min_planarity: float = Field(
        0.1,
        gt=0.0,
        le=1.0,
        description="a reference point less planar than this (a single scan line) counts in the covariance in proportion (default 0.1)",
    )
    voxel_grid: Literal["sensor", "scene"] = Field(
        "sensor",
        description="frame of the downsampling voxel grid: 'sensor' fixes it to each scan's sensor frame, as small_gicp's "
        "preprocess_points and PCL's VoxelGrid do, so it aliases with the motion (+39 mm a scan along the route under "
        "charles_river's lock road); 'scene' carries the reference's grid by the estimated motion (matcher.scene_grid: "
        "-0.2 mm there). Default sensor: as the default, 'scene' moved the library's metrics and crashed "
        "steer_canal_multipath's closed loop on one seed through a bad start-up (docs/models.md)",
    )
    keyframe_m: float = Field(
        1.0,
        ge=0.0,
        description="register each scan against a keyframe, kept until the motion from it exceeds this many metres or "
        "keyframe_deg, instead of against the previous scan (0: scan to scan) [1 m]. A registration's noise-driven yaw "
        "bias does not grow with the motion it spans, so the steps against one keyframe chain into one registration's: "
        "gicp's chained yaw over 30-40 s at four charles_river places fell from 0.38-0.96 to 0.21-0.26 deg, the library's "
        "gicp yaw p95 median 0.95 -> 0.46 deg and the ekf's APE p95 median 1.13 -> 0.89 m. The price: a ring's points on a "
        "deck overhead or a far wall move with the sensor and pull a match towards the reference, by up to a step scan "
        "to scan but up to keyframe_m against a keyframe (past the full quickstart's Museum of Science bridge the chain "
        "ran 27% slow and turned 0.17 deg/s, scan to scan 0.03); docs/models.md 'gicp against a keyframe'",
    )
    keyframe_deg: float = Field(10.0, gt=0.0, description="with keyframe_m: a new keyframe once the heading turned more than this, deg (default 10)")
    drop_comoving: bool = Field(True, description="drop returns from objects keeping station with the sensor, e.g. a chase boat (default true)")
    drop_movers: bool = Field(
        False,
        description="drop returns from objects moving on their own, boats under way (matcher.movers). On where boats are under "
        "way (busy_waterway seed 2: gicp yaw p95 15.6 -> 1.3 deg, ekf APE p95 4.25 -> 0.83 m). Default off: it judges "
        "against the motion prior, and a wrong prior the matcher claims to know drops the static structure that could "
        "correct it (the full quickstart, no boats: seed 4 ran 96 m off from 2005 s for 30 s, 14 m for 3 s without it; "
        "docs/models.md 'Boats under way')",
    )
    mover_min_speed_mps: float = Field(
        1.0,
        gt=0.0,
        description="an object moves on its own when its surfaces moved faster than this beyond the corrected motion prior, m/s "
        "(default 1: 0.1 m a revolution at 10 Hz, five times the range noise; slower boats pull little)",
    )
    mover_link_m: float = Field(
        2.0,
        gt=0.0,
        description="points in neighbouring voxels of this size belong to one object (default 2 m: a boat's rings stay joined "
        "to 80 m off, 1.33 deg apart)",
    )
    mover_max_extent_m: float = Field(
        60.0, gt=0.0, description="an object wider than this is the static world, never a mover (default 60 m: a barge and its tug)"
    )


STEP_GATE = 18.42
"""chi2.ppf(1 - 1e-4, 2): a step against a keyframe further than this (squared Mahalanobis) from the motion prior is redone
against the previous scan (Gicp._contradicts)."""

Screen = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
"""A de-skewed scan's points -> (moving with the sensor, to drop before registering)."""

_Alignment = tuple[Any, PlaneFit, np.ndarray, Degeneracy]
"""One de-skew round's small_gicp result, point-to-plane fit, the step's [x, y, z, roll, pitch, yaw] covariance and degeneracy."""


class _NearestPlane:
    """small_gicp's k-d tree behind the `query` that matcher.pointplane expects (scipy's cKDTree's)."""

    def __init__(self, tree: small_gicp.KdTree, n: int) -> None:
        self.tree, self.n = tree, n

    def query(self, q: np.ndarray, distance_upper_bound: float) -> tuple[np.ndarray, np.ndarray]:
        """Distance to and index of each point's nearest neighbour; inf and n beyond the bound."""
        idx, sq = self.tree.batch_nearest_neighbor_search(q)
        idx, dist = np.asarray(idx), np.sqrt(np.asarray(sq, dtype=float))
        far = (idx < 0) | (dist > distance_upper_bound)
        return np.where(far, np.inf, dist), np.where(far, self.n, idx)


class _Prepared:
    """A de-skewed, downsampled scan with covariances and its k-d tree."""

    def __init__(self, cloud: Cloud, twist: np.ndarray | None, grid: np.ndarray | None, p: GicpParams, screen: Screen | None = None) -> None:
        self.cloud, self.twist, self.grid = cloud, twist, grid
        xyz = deskew(cloud.xyz, cloud.time, twist)
        self.moving = np.empty((0, 3))  # points dropped as moving with the sensor (recalled by the next scan's screen)
        self.dropped = 0  # points dropped as moving, with the sensor or on their own
        if screen is not None:
            comoving, drop = screen(xyz)
            self.moving, self.dropped, xyz = xyz[comoving], int(drop.sum()), xyz[~drop]
        if grid is None:  # the sensor's own grid
            self.points, self.tree = small_gicp.preprocess_points(
                xyz, downsampling_resolution=p.voxel_m, num_neighbors=p.num_neighbors, num_threads=p.num_threads
            )
        else:
            self.points, self.tree = downsample(xyz, grid, p.voxel_m, p.num_neighbors, p.num_threads)
        self.xyz, self.normals = self.points.points()[:, :3], self.points.normals()[:, :3]
        self.nearest = _NearestPlane(self.tree, len(self.xyz))
        self._raw, self._p = xyz, p

    @cached_property
    def normal_weight(self) -> np.ndarray:
        """How far each point's normal can be trusted: its planarity over min_planarity, at most 1. Found when first
        wanted, as a reference's: a scan de-skewed again in a later round, or a failed one prepared again, never is."""
        return np.minimum(planarity(self._raw, self.xyz, self._p.planarity_voxel_m) / self._p.min_planarity, 1.0)

    def plane_fit(self, ref: _Prepared, T: np.ndarray, p: GicpParams) -> PlaneFit:
        """Point-to-plane information of this scan moved by T against the reference's planes (the
        partners' normals weighed by how well their surroundings define them)."""
        return point_to_plane_fit(self.xyz, T, ref.xyz, ref.normals, ref.nearest, p.max_correspondence_m, p.tukey_k_m, ref.normal_weight)


class Gicp(DeskewingMatcher[_Prepared]):
    """small_gicp GICP of each scan against the previous good one."""

    name = "gicp"

    def __init__(self, params: GicpParams) -> None:
        super().__init__(params)
        self.p = params
        self._from_key = np.eye(4)  # the reference (previous good scan) in the keyframe's lidar frame
        self._to_key: np.ndarray | None = None  # the scan just matched in the keyframe's frame; None: it may not keep it
        self._previous: _Prepared | None = None  # the reference as prepared when it was matched, for the moving screen

    def _prepare(self, cloud: Cloud, twist: np.ndarray | None, screen: Screen | None = None) -> _Prepared:
        return _Prepared(cloud, twist, self._grid(cloud, twist), self.p, screen)

    def _grid(self, cloud: Cloud, twist: np.ndarray | None) -> np.ndarray | None:
        """The voxel grid of `cloud`: None for the sensor's own (voxel_grid = "sensor"); else the reference's, carried
        by the motion `twist` gives over the time between them (matcher.scene_grid), the first scan's its own frame."""
        if self.p.voxel_grid == "sensor":
            return None
        if self._ref is None or self._ref.grid is None:
            return np.eye(4)
        motion = np.eye(4) if twist is None else se3_exp(twist * (cloud.stamp - self._ref.cloud.stamp))
        return carried(self._ref.grid, motion, self.p.voxel_m)

    def _moving_screen(self, prior: np.ndarray, dt: float) -> Screen | None:
        """The masks of a de-skewed scan's points moving with the sensor (matcher.comoving) and of those to drop, these
        and the ones on objects moving on their own (matcher.movers), against the previous good scan and the motion
        `prior` from it, found on the first de-skew and kept for the later ones (a point stays where it was within a
        few cm); None: both off. Only the former are remembered for the next scan (see matcher.movers). Against the
        previous scan, not an older keyframe: a chase boat drifts about its station by more than the recall's voxel
        over a keyframe's second, and judged against the keyframe half its returns stayed in (the chained forward
        motion entering a girder bridge 0.86 of the truth, 1.00 against the previous scan)."""
        p = self.p
        if not (p.drop_comoving or p.drop_movers):
            return None
        ref = self._previous if self._previous is not None else self._reference()
        test = MoverTest(p.mover_min_speed_mps, p.mover_link_m, p.mover_max_extent_m, p.max_correspondence_m)
        found: list[tuple[np.ndarray, np.ndarray]] = []

        def screen(xyz: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            if not found:
                comoving = np.zeros(len(xyz), dtype=bool)
                if p.drop_comoving:
                    comoving = moving_with_sensor(xyz, prior, ref.xyz, ref.normals, ref.nearest, ref.moving, p.max_correspondence_m, p.voxel_m)
                drop = comoving.copy()
                if p.drop_movers:
                    cov = self.velocity.translation_cov(dt)
                    drop |= moving_objects(xyz, prior, cov, dt, ref.xyz, ref.normals, ref.nearest, p.voxel_m, test)
                found.append((comoving, drop))
            return found[0]

        return screen

    def _held(self, degeneracy: Degeneracy, sigma2: float, answer: np.ndarray, prior: np.ndarray, dt: float) -> list[np.ndarray]:
        """The free translations along which the motion prior is kept. With no motion known yet (the identity
        predicted), only those the scans did not measure either: a standard deviation sqrt(sigma2 / information) of at
        least degenerate_sigma_m, the covariance's "unknown". Never a horizontal one (within 30 deg) along which GICP's
        `answer` travels farther from "no motion" than the prior does, by more than three of its own standard
        deviations: the bias a free direction has pulls towards no motion (the ring pattern moves with the sensor), so
        that answer is a measurement and the prior is what is wrong. canal_lock's canyon started gicp from a stopped boat
        (its first answer, 0 m for 0.2 m, is that bias) and kept that prior for 40 s; when a face across the canal then
        measured 0.20 m +- 2 cm a scan, keeping 0 m moved the misfit into pitch (the face's height couples the two), 1.4
        deg a scan: the chained odometry pitched past 90 deg in 7 s and read as a 180 deg turn. Unless the prior is a
        measured travel and the answer changes the speed by more than the prior's own uncertainty allows (both by three
        standard deviations of the predicted translation, the speed's random walk included:
        matcher.motion.SPEED_WALK_MPS_PER_SQRT_S): a boat cannot accelerate so, and the answer is the free direction's
        error, not travel. Under the quickstart stretch's Museum of Science bridge deck (seed 5) an answer of 0.82 m a
        scan against a prior of 0.29 m (truth 0.19 m) was taken, kept as the prior for the next 8 s of free steps, and
        the misfit went into pitch, 1.3 deg a scan, until the chain turned over (yaw error 158 deg at a success of
        0.999). A prior of no measured travel is never judged so: canal_lock's, born of the bias, would keep the face's
        0.20 m out (canal_multipath seed 2's chain then tilted until its yaw p95 read 14.6 deg); nor is a prior judged
        stopped by the answer's own spread (steel_bridge_compass [fast] seed 1: a prior of 0.18 m a scan within three of
        an answer's 6 cm counted as stopped, an answer of 1.50 m was taken, and the chain turned over). Not the
        vertical: a floating hull does not travel up or down, its heave oscillates, and in rough_water's waves one
        scan's heave taken as the vertical prior kept the boat sinking at 3 m/s."""
        known = self.velocity.twist_per_s is not None
        expected, travel = self.velocity.translation_cov(dt), self.velocity.predict(dt)[:3, 3]
        held = []
        for d, mu in zip(degeneracy.directions, degeneracy.direction_information, strict=True):
            if not d[:3].any():
                continue
            if mu <= 0:
                held.append(d)
                continue
            sigma = float(np.sqrt(sigma2 / mu))
            u = d[:3] / np.linalg.norm(d[:3])
            beyond = abs(float(answer[:3, 3] @ u)) > abs(float(prior[:3, 3] @ u)) + 3.0 * sigma
            reach = math.inf if expected is None else 3.0 * float(np.sqrt(u @ expected @ u))  # 3 sigma of the prior's travel
            stopped = abs(float(travel @ u)) <= reach  # no travel measured: what the free direction's bias leaves
            possible = stopped or abs(float((answer[:3, 3] - prior[:3, 3]) @ u)) <= reach
            if abs(u[2]) < 0.5 and beyond and possible:
                continue  # travel measured beyond the prior's, at a speed the boat can reach: not the free direction's bias
            if known or sigma >= self.p.degenerate_sigma_m:
                held.append(d)
        return held

    def _match(self, cloud: Cloud, dt: float) -> MatchResult:
        p = self.p
        step_prior = self.velocity.predict(dt)
        screen = self._moving_screen(step_prior, dt)
        ref, cur, aligned = self._against(self._reference(), self._from_key, cloud, dt, step_prior, screen)
        if aligned is not None and self._previous is not None and self._contradicts(aligned, step_prior, dt):
            ref, cur, aligned = self._against(self._previous, np.eye(4), cloud, dt, step_prior, screen)
            self._from_key, self._previous = np.eye(4), None  # the previous scan is the keyframe now
        if aligned is None:
            self._cur = cur
            return MatchResult.failure("too few points after downsampling")
        self._ref, self._cur = ref, cur
        T, (res, fit, cov, degeneracy) = aligned
        n_src = len(cur.xyz)
        inlier_share = res.num_inliers / n_src
        info: dict[str, Any] = {
            "converged": bool(res.converged),
            "iterations": int(res.iterations),  # of the last de-skew round
            "inlier_share": float(inlier_share),
            "points_used": n_src,
            "comoving_points": len(cur.moving),
            "moving_points": cur.dropped,
        }
        if inlier_share < p.min_inlier_share:
            return MatchResult.failure(f"inlier share {inlier_share:.2f} < min_inlier_share {p.min_inlier_share}", **info)
        self._to_key = None if _horizontally_degenerate(degeneracy) else self._from_key @ T
        info.update(degeneracy.as_info(), sigma2=fit.sigma2, plane_outlier_share=fit.outlier_share)
        return MatchResult(T=T, ok=True, cov=p.add_to(cov), n_points=0, seconds=0.0, info=info)

    def _against(
        self, key: _Prepared, from_key: np.ndarray, cloud: Cloud, dt: float, step_prior: np.ndarray, screen: Screen | None
    ) -> tuple[_Prepared, _Prepared, tuple[np.ndarray, _Alignment] | None]:
        """deskew_rounds of `cloud` against the keyframe `key`, in which the reference sits at `from_key`: the keyframe
        (re-prepared if it never was de-skewed), the prepared scan, and the step from the reference with GICP's result,
        point-to-plane fit, the step's [x, y, z, roll, pitch, yaw] covariance (floor not added) and degeneracy."""
        p = self.p
        back = np.linalg.inv(from_key)
        prior = from_key @ step_prior  # the predicted pose in the keyframe's frame

        def align(cur: _Prepared, key: _Prepared, T: np.ndarray | None) -> tuple[np.ndarray, _Alignment] | None:
            """The step from the reference (T: its guess) as GICP against the keyframe gives it, with what it measured."""
            if len(cur.xyz) < 6 or len(key.xyz) < 6:
                return None
            res = small_gicp.align(
                key.points,
                cur.points,
                key.tree,
                init_T_target_source=None if T is None else from_key @ T,
                registration_type=p.registration_type,
                max_correspondence_distance=p.max_correspondence_m,
                num_threads=p.num_threads,
                max_iterations=p.max_iterations,
                rotation_epsilon=p.rotation_epsilon_rad,
                translation_epsilon=p.translation_epsilon_m,
            )
            fit = cur.plane_fit(key, res.T_target_source, p)
            cov_param, degeneracy = covariance_from_hessian(fit.H, fit.sigma2, p.degenerate_ratio, p.degenerate_sigma_m, p.degenerate_sigma_rad)
            T = back @ keep_prior_along(res.T_target_source, prior, fit.H, self._held(degeneracy, fit.sigma2, res.T_target_source, prior, dt))
            # GICP's left perturbation of the pose in the keyframe's frame, carried into the step's: Exp(Ad(back) xi) T
            cov = to_xyzrpy(adjoint(back) @ cov_param @ adjoint(back).T, left_perturbation_jacobian(T))
            return T, (res, fit, cov, degeneracy)

        prepare = lambda c, twist: self._prepare(c, twist, screen)
        return deskew_rounds(cloud, key, self.velocity.twist_per_s, step_prior, dt, p.deskew_iterations, prepare, align, self._prepare)

    def _contradicts(self, aligned: tuple[np.ndarray, _Alignment], step_prior: np.ndarray, dt: float) -> bool:
        """Whether a step measured against an older keyframe moved the boat in the plane farther from the motion prior
        than the speed's random walk and both covariances allow (chi-square, 2 dof, 1e-4). Overhead structure's ring
        pattern moves with the sensor and pulls a match towards "no motion since the reference": against the previous
        scan that is at most a step, against a keyframe up to keyframe_m. Entering a beam bridge's deck the keyframe's
        matches slid back 0.44 m a step with a 4 cm sigma, where the previous scan's flagged the motion unmeasured."""
        expected = self.velocity.translation_cov(dt)
        if expected is None:
            return False
        T, (_, _, cov, _) = aligned
        d = T[:2, 3] - step_prior[:2, 3]
        return float(d @ np.linalg.solve(expected[:2, :2] + cov[:2, :2], d)) > STEP_GATE

    def _commit(self, ok: bool) -> None:
        """The scan just matched becomes the reference; it becomes the keyframe too after a failed match, with
        keyframe_m = 0, once the motion from the keyframe exceeds keyframe_m or keyframe_deg, or when the match left a
        horizontal direction or the heading unmeasured (there the kept prior is the answer, and a prior carried from
        an older keyframe compounds: under charles_river's Museum of Science bridge deck the chain ran 105 m along
        the route in 23 s against 49 m scan to scan, and turned 10 deg after it against 2)."""
        to_key, self._to_key = self._to_key, None
        if ok and to_key is not None and self.p.keyframe_m > 0.0 and not self._far(to_key):
            self._previous, self._cur = self._cur, None
            self._from_key = to_key
        else:
            super()._commit(ok)
            self._from_key, self._previous = np.eye(4), None

    def _far(self, to_key: np.ndarray) -> bool:
        """Whether the motion from the keyframe exceeds keyframe_m or keyframe_deg."""
        motion = pose_to_xyzrpy(to_key)
        return bool(np.linalg.norm(motion[:3]) > self.p.keyframe_m or abs(np.degrees(motion[5])) > self.p.keyframe_deg)

    def _reset(self) -> None:
        super()._reset()
        self._from_key, self._to_key, self._previous = np.eye(4), None, None


def _horizontally_degenerate(degeneracy: Degeneracy) -> bool:
    """Whether a degenerate direction of the match leans on a horizontal translation or the heading (more than 30 deg
    from the vertical, roll and pitch): the vertical alone is free over open water and says nothing of the track."""
    return any(max(abs(d[0]), abs(d[1]), abs(d[5])) > 0.5 for d in degeneracy.directions)
