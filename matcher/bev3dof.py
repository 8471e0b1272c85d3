"""bev3dof: the field study's Method 2, 3-DoF registration of bird's-eye-view images (yaw, x, y).

Each scan is de-skewed, cut to a height band and binned onto the x-y plane (pixel size and extent
as parameters; points outside are dropped). Consecutive images are registered by a global step
(Fourier-Mellin: rotation from phase correlation of the polar-resampled magnitude spectra, then
translation by phase correlation; or an exhaustive yaw search) and refined to sub-pixel precision
by ECC with a Euclidean motion model. The ECC correlation is the confidence; a weak one fails."""

from __future__ import annotations

from typing import Literal

import cv2
import numpy as np
from pydantic import Field

from matcher.base import Matcher, MatcherParams
from matcher.cloud import Cloud
from matcher.covariance import DegeneracyParams, covariance_from_hessian, right_perturbation_jacobian, to_xyzrpy
from matcher.motion import deskew_planar, gram, planar, pose_to_xyzrpy, se3_log, twist_changed
from matcher.result import MatchResult


class Bev3dofParams(MatcherParams, DegeneracyParams):
    """Settings of the `bev3dof` matcher."""

    pixel_m: float = Field(0.3, gt=0.0, description="image pixel size (default 0.3 m)")
    extent_m: float = Field(45.0, gt=0.0, description="half side of the square image around the lidar; points outside are dropped (default 45 m)")
    z_min_m: float = Field(-5.0, description="lowest point height in the lidar frame that is drawn (default -5 m)")
    z_max_m: float = Field(25.0, description="highest point height in the lidar frame that is drawn (default 25 m)")
    image: Literal["vertical", "count"] = Field(
        "vertical",
        description="pixel value: 'vertical' = std. dev. of point heights in the pixel (walls, piers, buildings; flat ground and water, "
        "whose scan-ring pattern moves with the sensor, stay dark), 'count' = log point count (default vertical)",
    )
    vertical_clip_m: float = Field(2.0, gt=0.0, description="'vertical' image: height std. dev. clipped at this value (default 2 m)")
    blur_px: float = Field(1.0, ge=0.0, description="Gaussian blur of the image, std. dev. in pixels (default 1)")
    global_method: Literal["fourier_mellin", "yaw_search"] = Field("fourier_mellin", description="global step (default fourier_mellin)")
    yaw_search_step_deg: float = Field(1.0, gt=0.0, description="yaw_search: step (default 1 deg)")
    yaw_search_range_deg: float = Field(180.0, gt=0.0, le=180.0, description="yaw_search: +- range (default 180 deg)")
    skip_global_max_dt_s: float = Field(
        0.25,
        ge=0.0,
        description="skip the global step (refine from the motion prior, or identity) when scans are at most this far apart (default 0.25 s)",
    )
    ecc_iterations: int = Field(50, ge=1, description="ECC iterations (default 50)")
    ecc_eps: float = Field(1e-5, gt=0.0, description="ECC convergence threshold (default 1e-5)")
    ecc_gauss_px: int = Field(5, ge=1, description="ECC Gaussian pre-filter size, odd pixels (default 5)")
    deskew_iterations: int = Field(1, ge=1, description="image/register rounds; later rounds de-skew both scans with the new estimate (default 1)")
    min_correlation: float = Field(0.85, ge=-1.0, le=1.0, description="ECC correlation below which the match fails (default 0.85)")
    floor_sigma_m: float = Field(0.03, ge=0.0, description="std. dev. added to x and y for pixel quantisation and de-skew (default 3 cm = 0.1 px)")
    floor_sigma_yaw_rad: float = Field(0.0005, ge=0.0, description="std. dev. added to yaw, likewise (default 0.5 mrad)")
    unobserved_sigma_m: float = Field(1.0, gt=0.0, description="std. dev. reported for z, which the method does not observe (default 1 m)")
    unobserved_sigma_rad: float = Field(0.1, gt=0.0, description="std. dev. reported for roll and pitch (default 0.1 rad)")


class _Image:
    """Bird's-eye view of one de-skewed scan: log point counts per pixel, blurred (float32)."""

    def __init__(self, xy: np.ndarray, z: np.ndarray, time: np.ndarray, twist: np.ndarray | None, p: Bev3dofParams) -> None:
        self.xy, self.z, self.time, self.twist, self.p = xy, z, time, twist, p
        n = int(round(2 * p.extent_m / p.pixel_m))
        uv = (deskew_planar(xy, time, twist) + p.extent_m) * (1.0 / p.pixel_m)
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < n) & (uv[:, 1] >= 0) & (uv[:, 1] < n)
        ij = uv[inside].astype(np.int64)  # truncation is floor here: all coordinates are >= 0
        flat = ij[:, 1] * n + ij[:, 0]
        counts = np.bincount(flat, minlength=n * n)
        if p.image == "count":
            img = np.log1p(counts.astype(np.float32)).reshape(n, n)
        else:
            zin = z[inside] - z[inside].mean() if inside.any() else z[inside]
            s1 = np.bincount(flat, weights=zin, minlength=n * n)
            s2 = np.bincount(flat, weights=zin * zin, minlength=n * n)
            safe = np.maximum(counts, 1)
            var = np.clip(s2 / safe - (s1 / safe) ** 2, 0.0, None)
            img = np.minimum(np.sqrt(var), p.vertical_clip_m).astype(np.float32).reshape(n, n)
        if p.blur_px > 0:
            img = cv2.GaussianBlur(img, (0, 0), p.blur_px)
        self.image = img
        self.points_drawn = int(inside.sum())

    @classmethod
    def of(cls, cloud: Cloud, twist: np.ndarray | None, p: Bev3dofParams) -> _Image:
        """Image of the cloud's points inside the height band."""
        band = (cloud.xyz[:, 2] >= p.z_min_m) & (cloud.xyz[:, 2] <= p.z_max_m)
        return cls(cloud.xyz[band, :2], cloud.xyz[band, 2], cloud.time[band], twist, p)

    def with_twist(self, twist: np.ndarray | None) -> _Image:
        """The same points de-skewed with another twist."""
        return self if not twist_changed(self.twist, twist, 1.0, 1e-9, 1e-9) else _Image(self.xy, self.z, self.time, twist, self.p)


def _ncc(a: np.ndarray, b: np.ndarray) -> float:
    a, b = a - a.mean(), b - b.mean()
    den = float(np.sqrt((a * a).sum() * (b * b).sum()))  # elementwise sums: no BLAS thread wake-ups
    return float((a * b).sum() / den) if den > 0 else 0.0


class Bev3dof(Matcher):
    """Method 2: x-y image registration for yaw, x and y."""

    name = "bev3dof"

    def __init__(self, params: Bev3dofParams) -> None:
        super().__init__(params)
        self.p = params
        n = int(round(2 * params.extent_m / params.pixel_m))
        c = 0.5 * params.pixel_m - params.extent_m
        self._n = n
        self._px2m = np.array([[params.pixel_m, 0, c], [0, params.pixel_m, c], [0, 0, 1.0]])
        self._m2px = np.linalg.inv(self._px2m)
        self._window = cv2.createHanningWindow((n, n), cv2.CV_32F)
        centres = (np.arange(n // 2) + 0.5) * 2.0 * params.pixel_m - params.extent_m  # of the half-resolution pixels
        self._centre_x = np.tile(centres, len(centres))
        self._centre_y = np.repeat(centres, len(centres))
        self._ref: _Image | None = None
        self._cur: _Image | None = None

    def _start(self, cloud: Cloud) -> None:
        self._ref = _Image.of(cloud, None, self.p)

    def _images(self, cloud: Cloud, twist: np.ndarray | None, dt: float) -> tuple[_Image, _Image]:
        """Reference and current images, both de-skewed with the same twist, so a wrong twist
        distorts both alike instead of feeding back into the next estimate. The reference keeps
        its twist (no re-render) until the motion prior has moved away from it noticeably."""
        ref = self._ref
        assert ref is not None  # _start draws it
        if twist_changed(ref.twist, twist, dt):
            ref = ref.with_twist(twist)
        return ref, _Image.of(cloud, ref.twist, self.p)

    def _reset(self) -> None:
        self._ref = self._cur = None

    def _commit(self, ok: bool) -> None:
        cur = self._cur
        assert cur is not None  # every _match keeps the image it drew
        self._ref, self._cur = (cur if ok else cur.with_twist(self.velocity.twist_per_s)), None

    # warps: W maps current-image pixels to previous-image pixels; in metres it is the 2-D pose
    def _warp_of(self, x: float, y: float, yaw: float) -> np.ndarray:
        c, s = np.cos(yaw), np.sin(yaw)
        return self._m2px @ np.array([[c, -s, x], [s, c, y], [0, 0, 1.0]]) @ self._px2m

    def _pose_of(self, W: np.ndarray) -> tuple[float, float, float]:
        M = self._px2m @ W @ self._m2px
        return float(M[0, 2]), float(M[1, 2]), float(np.arctan2(M[1, 0], M[0, 0]))

    def _warped_prev(self, prev: np.ndarray, W: np.ndarray) -> np.ndarray:
        """prev sampled at W(u) for every current pixel u."""
        return cv2.warpAffine(prev, W[:2].astype(np.float32), (self._n, self._n), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP)

    def _candidates_fourier_mellin(self, prev: np.ndarray, cur: np.ndarray) -> tuple[list[float], float]:
        n = self._n
        spectra = []
        for img in (prev, cur):
            F = np.fft.fftshift(np.abs(np.fft.fft2(img * self._window)))
            spectra.append(np.log1p(F).astype(np.float32))
        n_theta = 360
        polar = [cv2.warpPolar(S, (n // 2, n_theta), (n / 2, n / 2), n / 2, cv2.WARP_POLAR_LINEAR) for S in spectra]
        polar = [pl[:, 2:] for pl in polar]  # drop the DC neighbourhood
        (_, dy), response = cv2.phaseCorrelate(polar[0], polar[1])
        theta = np.radians(dy * 360.0 / n_theta)
        return [theta, -theta, theta + np.pi, -theta + np.pi], float(response)

    def _candidates_yaw_search(self, prev: np.ndarray, cur: np.ndarray) -> tuple[list[float], float]:
        p = self.p
        yaws = np.radians(np.arange(-p.yaw_search_range_deg, p.yaw_search_range_deg + 1e-9, p.yaw_search_step_deg))
        scores = []
        for yaw in yaws:
            warped = self._warped_prev(prev, self._warp_of(0.0, 0.0, yaw))
            scores.append(cv2.phaseCorrelate(cur, warped)[1])
        best = int(np.argmax(scores))
        return [float(yaws[best])], float(scores[best])

    def _global(self, prev: np.ndarray, cur: np.ndarray) -> tuple[np.ndarray, dict]:
        """Initial warp from the global step: best of the yaw candidates with phase-correlated shifts."""
        find = self._candidates_fourier_mellin if self.p.global_method == "fourier_mellin" else self._candidates_yaw_search
        yaws, response = find(prev, cur)
        best, best_score = np.eye(3), -np.inf
        for yaw in yaws:
            W_rot = self._warp_of(0.0, 0.0, yaw)
            (dx, dy), _ = cv2.phaseCorrelate(cur, self._warped_prev(prev, W_rot))
            for sign in (1.0, -1.0):
                W = W_rot @ np.array([[1, 0, sign * dx], [0, 1, sign * dy], [0, 0, 1.0]])
                score = _ncc(self._warped_prev(prev, W), cur)
                if score > best_score:
                    best, best_score = W, score
        return best, {"global_response": response, "global_correlation": float(best_score)}

    def _ecc(self, prev: np.ndarray, cur: np.ndarray, W0: np.ndarray) -> tuple[float, np.ndarray]:
        p = self.p
        criteria = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, p.ecc_iterations, p.ecc_eps)
        try:
            # OpenCV's stubs type inputMask as a Mat in the form with gaussFiltSize; the binding takes None (no mask)
            cc, W = cv2.findTransformECC(  # type: ignore[call-overload]
                cur, prev, W0[:2].astype(np.float32), cv2.MOTION_EUCLIDEAN, criteria, None, p.ecc_gauss_px
            )
        except cv2.error:  # OpenCV gives up when the images do not correlate
            return -np.inf, W0
        return float(cc), np.vstack([W.astype(np.float64), [0, 0, 1.0]])

    def _covariance(self, prev: np.ndarray, cur: np.ndarray, W: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, dict]:
        """Fisher information of the normalised image residual in [x, y, yaw] (right perturbation),
        on both images averaged down to half resolution (the blurred pixels are correlated anyway)."""
        p = self.p
        half = (self._n // 2, self._n // 2)
        a = cv2.resize(self._warped_prev(prev, W), half, interpolation=cv2.INTER_AREA)
        b = cv2.resize(cur, half, interpolation=cv2.INTER_AREA)
        a, b = a - a.mean(), b - b.mean()
        na, nb = max(float(np.sqrt((a * a).sum())), 1e-12), max(float(np.sqrt((b * b).sum())), 1e-12)  # no BLAS dot
        scale = 1.0 / (8.0 * 2.0 * p.pixel_m * na)  # Sobel sum -> derivative of a / |a| per metre
        gx = cv2.Sobel(a, cv2.CV_32F, 1, 0, ksize=3).ravel()
        gy = cv2.Sobel(a, cv2.CV_32F, 0, 1, ksize=3).ravel()
        support = np.flatnonzero((gx != 0) | (gy != 0))  # pixels without gradient add nothing to H
        gx, gy = gx[support].astype(np.float64) * scale, gy[support].astype(np.float64) * scale
        X, Y = self._centre_x[support], self._centre_y[support]
        J = np.stack([gx, gy, gy * X - gx * Y], axis=1)
        H = gram(J)
        r = (a / na - b / nb).ravel().astype(np.float64)
        correlated_px = max(np.pi * p.blur_px**2, 1.0)  # residuals are correlated over the blur kernel (in half pixels)
        sigma2 = float((r * r).sum()) / max(r.size - 3, 1) * correlated_px
        cov3, degeneracy = covariance_from_hessian(H, sigma2, p.degenerate_ratio, p.degenerate_sigma_m, p.degenerate_sigma_rad, (False, False, True))
        cov3 += np.diag([p.floor_sigma_m**2, p.floor_sigma_m**2, p.floor_sigma_yaw_rad**2])  # quantisation adds to the image noise
        cov_param = np.diag([0.0, 0.0, p.unobserved_sigma_m**2, p.unobserved_sigma_rad**2, p.unobserved_sigma_rad**2, 0.0])
        idx = [0, 1, 5]
        cov_param[np.ix_(idx, idx)] = cov3
        return to_xyzrpy(cov_param, right_perturbation_jacobian(T)), degeneracy.as_info()

    def _pose3(self, W: np.ndarray) -> np.ndarray:
        x, y, yaw = self._pose_of(W)
        T = np.eye(4)
        T[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
        T[:2, 3] = x, y
        return T

    def _match(self, cloud: Cloud, dt: float) -> MatchResult:
        p = self.p
        prev, cur = self._images(cloud, self.velocity.twist_per_s, dt)
        twist = cur.twist
        self._cur = cur
        if cur.points_drawn < 10 or prev.points_drawn < 10:
            return MatchResult.failure("too few points in the image")
        info: dict = {"points_drawn": cur.points_drawn, "global": False}
        cc = -np.inf
        if dt <= p.skip_global_max_dt_s:  # start from the motion prior (identity without one: a boat moves little)
            x, y, _, _, _, yaw = pose_to_xyzrpy(planar(self.velocity.predict(dt)))
            cc, W = self._ecc(prev.image, cur.image, self._warp_of(x, y, yaw))
        if cc < p.min_correlation:
            W0, ginfo = self._global(prev.image, cur.image)
            info.update(ginfo, **{"global": True})
            cc, W = self._ecc(prev.image, cur.image, W0)
        for _ in range(p.deskew_iterations - 1):
            if cc < p.min_correlation:
                break
            new_twist = se3_log(self._pose3(W)) / dt
            if not twist_changed(new_twist, twist, dt):
                break
            prev, cur = self._images(cloud, new_twist, dt)
            twist = cur.twist
            self._cur = cur
            cc, W = self._ecc(prev.image, cur.image, W)
        info["peak"] = cc
        if cc == -np.inf:
            return MatchResult.failure("ECC refinement failed: the images do not correlate", **info)
        if cc < p.min_correlation:
            return MatchResult.failure(f"weak correlation peak {cc:.2f} < min_correlation {p.min_correlation}", **info)
        T = self._pose3(W)
        cov, dinfo = self._covariance(prev.image, cur.image, W, T)
        info.update(dinfo)
        return MatchResult(T=T, ok=True, cov=cov, n_points=0, seconds=0.0, info=info)
