"""The LiDAR's rays against the traffic: each ray meets each mover where the mover was at that ray's firing time.

The revolution is cast against the static world first (sim.lidar). Then, per mover, the rays that
can reach it are picked without touching every ray: the sensor's pose-knot intervals (8 firings,
0.37 ms) whose azimuth sector and elevation span meet the cone of the mover's bounding sphere seen
from the sensor, then the (interval, laser) cells of those near the cone's axis, then the rays of
those cells not already stopped nearer. They go into the mover's body frame at their own firing
time and are cast against the mover's body-frame scene, built once; the nearer hit wins. A moving
boat is thus smeared in the scan by its speed times the firing-time differences, as a real one is.

Mover poses are evaluated every MOVER_KNOT_FIRINGS firings (2.9 ms) and interpolated linearly in
between (per firing, like the sensor's own pose): exact for constant-velocity straight motion, and
on a boat turning at 0.1 rad/s at 5 m/s off by less than 1e-6 m.
"""

from __future__ import annotations

import numpy as np

from riverbench.angles import wrap_angle
from sim.movers import rigid_inverse
from sim.traffic import Traffic

SPHERE_PAD_M = 0.01
"""Added to each mover's bounding-sphere radius in the ray selection (float32 ray directions, interpolation)."""
SLAB_PAD_RAD = 1e-3
"""Added to the slab's elevation window besides the sensor's tilt (float32 ray directions)."""
MOVER_KNOT_FIRINGS = 64
"""Firings between two evaluations of a mover's pose."""


def _knots(n_firings: int, step: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Knot firings (every `step` and the last), and each firing's (0..n_firings) knot interval and position in it."""
    firing = np.arange(n_firings + 1)
    knot = np.r_[firing[::step], firing[-1]] if n_firings % step else firing[::step]
    index = np.minimum(firing // step, len(knot) - 2)
    return knot, index, (firing - knot[index]) / np.diff(knot)[index]


class MoverRays:
    """A sensor's fixed firing geometry, prepared once, to cast its revolutions' rays against moving bodies.

    ray_dir (n_firings, lasers, 3) and azimuth (n_firings, lasers) of every ray in the lidar frame;
    knot_firing (K + 1,) the firing at each of the sensor's pose knots; firing_s the firing period.
    """

    def __init__(self, ray_dir: np.ndarray, azimuth: np.ndarray, knot_firing: np.ndarray, firing_s: float):
        n_firings, self.lasers = azimuth.shape
        self.ray_dir_grid = np.concatenate([ray_dir, ray_dir[-1:]])  # (n_firings + 1, lasers, 3): a firing index may be the end
        self.knot_firing = knot_firing
        self.fires = np.diff(knot_firing)
        first, last = azimuth[knot_firing[:-1], 0], azimuth[knot_firing[1:] - 1, -1]
        self.az_mid, self.az_half = (first + last) / 2.0, (first - last) / 2.0
        elevation = np.arcsin(ray_dir[0, :, 2])
        self.laser_el = elevation
        self.el_lo, self.el_hi = float(elevation.min()), float(elevation.max())
        # direction of the middle of each (interval, laser) cell; a ray lies within az_half of it
        self.cell_dir = np.stack(
            [
                np.cos(elevation) * np.cos(self.az_mid)[:, None],
                np.cos(elevation) * np.sin(self.az_mid)[:, None],
                np.broadcast_to(np.sin(elevation), (len(self.az_mid), self.lasers)),
            ],
            axis=-1,
        )
        mover_knot, self.mover_index, self.mover_frac = _knots(n_firings, MOVER_KNOT_FIRINGS)
        self.mover_knot_t = mover_knot * firing_s

    def cast(
        self,
        traffic: Traffic,
        t0: float,
        lidar_knots: np.ndarray,
        firing_poses: np.ndarray,
        t_hit: np.ndarray,
        cos_inc: np.ndarray,
        max_range_m: float,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Update t_hit and cos_inc (per ray, in place) where a mover is nearer; the rays a mover hit first (sorted)
        and that mover's index.

        lidar_knots (K + 1, 4, 4) and firing_poses (n_firings + 1, 4, 4): world<-lidar of the revolution at t0.
        Every step but each mover's own cast runs on all movers at once.
        """
        mover_of_ray = np.full(len(t_hit), -1, dtype=np.int16)
        knots = traffic.poses(t0 + self.mover_knot_t)  # (M, mover knots, 4, 4)
        centre = np.stack([m.sphere[0] for m in traffic.movers])
        radius = np.array([m.sphere[1] for m in traffic.movers])
        half = np.stack([np.ptp(np.asarray(m.mesh.bounds), axis=0) / 2.0 for m in traffic.movers])
        half_height = np.einsum("mkj,mj->mk", np.abs(knots[..., 2, :3]), half).max(axis=1)  # of the box, over the revolution
        world_centre = np.einsum("mkij,mj->kmi", knots[..., :3, :3], centre) + knots[..., :3, 3].transpose(1, 0, 2)
        rel = self._at_firings(world_centre, self.knot_firing) - lidar_knots[:, None, :3, 3]  # (K + 1, M, 3) world
        p = np.einsum("kji,kmj->mki", lidar_knots[:, :3, :3], rel)  # sphere centres in the lidar frame
        tilt = np.arccos(np.clip(lidar_knots[:, 2, 2], -1.0, 1.0))
        rays, mover, grid_mover, grid_firing, at = self._candidates(
            p, radius, rel.transpose(1, 0, 2), half_height, np.maximum(tilt[:-1], tilt[1:]), t_hit, max_range_m
        )
        if not len(rays):
            return np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.int16)
        inv = rigid_inverse(knots.reshape(-1, 4, 4)).reshape(knots.shape)
        i, frac = self.mover_index[grid_firing], self.mover_frac[grid_firing, None, None]
        body_of_lidar = (inv[grid_mover, i] + frac * (inv[grid_mover, i + 1] - inv[grid_mover, i])) @ firing_poses[grid_firing]
        # every laser of the candidate firings in one batched product, then the candidate rays picked out
        directions = np.matmul(self.ray_dir_grid[grid_firing], body_of_lidar[:, :3, :3].transpose(0, 2, 1))
        directions = directions.reshape(-1, 3)[at * self.lasers + rays % self.lasers]
        origins = body_of_lidar[at, :3, 3]
        for index, body in enumerate(traffic.movers):
            mine = np.flatnonzero(mover == index)
            if not len(mine):
                continue
            t_mover, normals = body.cast(origins[mine], directions[mine])
            nearer = t_mover < t_hit[rays[mine]]
            won = rays[mine[nearer]]
            t_hit[won] = t_mover[nearer]
            cos_inc[won] = np.abs(np.einsum("ij,ij->i", normals[nearer], directions[mine[nearer]]))
            mover_of_ray[won] = index
        hit = np.flatnonzero(mover_of_ray >= 0)
        return hit, mover_of_ray[hit]

    @staticmethod
    def _slab(rel: np.ndarray, half_height: np.ndarray, reach: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World elevation window (low, high) of a slab of half_height about centres rel (P, 3) from the sensor, whose
        points lie within `reach` (P,) of the centre horizontally."""
        horizontal = np.hypot(rel[:, 0], rel[:, 1])
        near, far = np.maximum(horizontal - reach, 1e-6), horizontal + reach
        bottom, top = rel[:, 2] - half_height, rel[:, 2] + half_height
        return (np.arctan2(bottom, np.where(bottom < 0, near, far)), np.arctan2(top, np.where(top < 0, far, near)))

    def _at_firings(self, values: np.ndarray, firing: np.ndarray) -> np.ndarray:
        """Values given at the mover knots (first axis) interpolated linearly to the firings `firing`."""
        i = self.mover_index[firing]
        frac = self.mover_frac[firing].reshape(-1, *([1] * (values.ndim - 1)))
        return values[i] + frac * (values[i + 1] - values[i])

    def _candidates(
        self, p: np.ndarray, radius: np.ndarray, rel: np.ndarray, half_height: np.ndarray, tilt: np.ndarray, t_hit: np.ndarray, max_range_m: float
    ):
        """Rays that may meet the movers before their current hit: (rays, their mover, the (mover, firing) grid of the
        candidate intervals as grid_mover and grid_firing, each ray's row in that grid).

        A mover is bounded by a sphere (radius (M,) about p (M, K + 1, 3), its centre in the lidar frame at each
        sensor knot) and by a horizontal slab (half_height (M,) about the centre, rel (M, K + 1, 3) in the world
        frame): the slab's elevation window, widened by the sensor's tilt (K,), cuts most of the sphere's lasers.
        """
        r = radius[:, None] + SPHERE_PAD_M + np.linalg.norm(np.diff(p, axis=1), axis=2)  # (M, K)
        p = p[:, :-1]
        dist = np.linalg.norm(p, axis=2)
        horizontal = np.hypot(p[..., 0], p[..., 1])
        inside = dist <= r
        with np.errstate(divide="ignore", invalid="ignore"):
            half_az = np.where(horizontal > r, np.arcsin(np.minimum(r / horizontal, 1.0)), np.pi)
            half_cone = np.where(inside, np.pi, np.arcsin(np.minimum(r / dist, 1.0)))
        elevation = np.arctan2(p[..., 2], horizontal)
        keep = np.abs(wrap_angle(np.arctan2(p[..., 1], p[..., 0]) - self.az_mid)) <= half_az + self.az_half
        keep &= (elevation + half_cone >= self.el_lo) & (elevation - half_cone <= self.el_hi) & (dist - r <= max_range_m)
        mi, ji = np.nonzero(keep)  # candidate (mover, interval) pairs
        # cells whose middle is within the cone widened by the cell's own azimuth half-width
        axis = p[mi, ji] / np.maximum(dist[mi, ji], 1e-9)[:, None]
        reach = np.cos(np.minimum(half_cone[mi, ji] + self.az_half[ji], np.pi))
        in_cone = np.einsum("plk,pk->pl", self.cell_dir[ji], axis) >= reach[:, None]
        low, high = self._slab(rel[mi, ji], half_height[mi] + r[mi, ji] - radius[mi], r[mi, ji])
        pad = tilt[ji] + SLAB_PAD_RAD
        in_slab = (self.laser_el >= (low - pad)[:, None]) & (self.laser_el <= (high + pad)[:, None])
        pair, laser = np.nonzero(in_cone & in_slab)
        step = np.arange(self.fires.max())
        grid_firing = np.minimum(self.knot_firing[ji][:, None] + step, self.knot_firing[-1]).ravel()
        valid = step < self.fires[ji[pair]][:, None]
        at = (pair[:, None] * len(step) + step)[valid]
        pair = np.broadcast_to(pair[:, None], valid.shape)[valid]
        rays = grid_firing[at] * self.lasers + np.broadcast_to(laser[:, None], valid.shape)[valid]
        ok = t_hit[rays] > (dist[mi, ji] - r[mi, ji])[pair]
        return rays[ok], mi[pair[ok]], np.repeat(mi, len(step)), grid_firing, at[ok]
