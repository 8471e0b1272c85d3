"""Moving objects: a rigid body mesh with a material and a motion, and the motions other boats follow.

A motion answers `poses(ts) -> (N, 4, 4)` world<-body (x forward, y left, z up from the
waterline), level on the water (yaw only; other boats' wave motion is left out). The kinematics
are deliberately simple and exact: constant speed along a path with the path's smooth heading.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Protocol

import numpy as np
import open3d as o3d
import trimesh

from sim.multipath import MIN_FACET_AREA_M2, VERTICAL_NZ, FacadeIndex, Reflections
from worlds.materials import Material
from worlds.route import Route


class Motion(Protocol):
    def poses(self, ts: np.ndarray) -> np.ndarray:
        """(N, 4, 4) world<-body at times ts (N,)."""


def level_poses(xy: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(N, 4, 4) poses on the water surface (z = 0) at positions xy (N, 2) heading yaw (N,)."""
    out = np.zeros((len(yaw), 4, 4))
    c, s = np.cos(yaw), np.sin(yaw)
    out[:, 0, 0], out[:, 0, 1], out[:, 1, 0], out[:, 1, 1] = c, -s, s, c
    out[:, 2, 2] = out[:, 3, 3] = 1.0
    out[:, :2, 3] = xy
    return out


def rigid_inverse(poses: np.ndarray) -> np.ndarray:
    """(N, 4, 4) inverses of rigid transforms (N, 4, 4): [R^T, -R^T t]."""
    inv = np.zeros_like(poses)
    rt = poses[:, :3, :3].transpose(0, 2, 1)
    inv[:, :3, :3] = rt
    inv[:, :3, 3] = -np.einsum("nij,nj->ni", rt, poses[:, :3, 3])
    inv[:, 3, 3] = 1.0
    return inv


@dataclass(frozen=True)
class AlongRoute:
    """Constant speed along the route, `lateral_m` left of its centreline, at route station `station_m` at
    time `time_s`; `oncoming` boats travel down the route (heading turned by 180 deg). The speed is exact on
    the centreline (an offset path on a bend is a little longer or shorter); the boat holds at the route's ends."""

    route: Route
    station_m: float
    time_s: float
    speed_mps: float
    lateral_m: float = 0.0
    oncoming: bool = False

    def poses(self, ts: np.ndarray) -> np.ndarray:
        sign = -1.0 if self.oncoming else 1.0
        xy, heading = self.route.at(self.station_m + sign * self.speed_mps * (np.asarray(ts, dtype=float) - self.time_s))
        xy = xy + self.lateral_m * np.stack([-np.sin(heading), np.cos(heading)], axis=-1)
        return level_poses(xy, heading + (np.pi if self.oncoming else 0.0))


@dataclass(frozen=True)
class Crossing:
    """A straight line across the river at constant speed and heading: through `point` at time `time_s`,
    travelling `lo`..`hi` metres along `direction` (unit, 2-D) from it and waiting at those ends (its landings)."""

    point: np.ndarray
    direction: np.ndarray
    time_s: float
    speed_mps: float
    lo: float
    hi: float

    @classmethod
    def across(cls, route: Route, station_m: float, time_s: float, speed_mps: float, angle_deg: float, margin_m: float) -> Crossing:
        """Crossing the route's centreline at `station_m`, heading `angle_deg` from the route's direction (90: from
        the right bank to the left), landings `margin_m` inside the banks (the route's bank distances there)."""
        xy, heading = route.at(station_m)
        yaw = float(heading) + np.deg2rad(angle_deg)
        across = abs(np.sin(np.deg2rad(angle_deg)))
        left, right = np.interp(station_m, route.s, route.left_m), np.interp(station_m, route.s, route.right_m)
        if angle_deg < 0:
            left, right = right, left
        hi, lo = left / across - margin_m, -(right / across - margin_m)
        if lo >= hi:
            raise ValueError(
                f"crossing at station {station_m} m: the river ({left + right:.0f} m) is narrower than the landing margins ({2 * margin_m:.0f} m)"
            )
        return cls(np.asarray(xy, dtype=float), np.array([np.cos(yaw), np.sin(yaw)]), time_s, speed_mps, lo, hi)

    def poses(self, ts: np.ndarray) -> np.ndarray:
        travel = np.clip(self.speed_mps * (np.asarray(ts, dtype=float) - self.time_s), self.lo, self.hi)
        yaw = np.full(len(travel), np.arctan2(self.direction[1], self.direction[0]))
        return level_poses(self.point + travel[:, None] * self.direction, yaw)


@dataclass(frozen=True)
class Chase:
    """Follows a vessel (anything with `.poses(ts)` world<-base_link) `distance_m` behind and `lateral_m` to the left
    of where it was `lag_s` earlier, level, on its heading then (lag > 0: in its wake, turning where it turned).
    It asks the vessel only for times <= the time asked and >= `t_start` (where the vessel's trajectory begins),
    so a closed-loop vessel that knows only its past can be chased."""

    vessel: Motion
    distance_m: float
    lateral_m: float
    lag_s: float = 0.0
    t_start: float = 0.0

    def poses(self, ts: np.ndarray) -> np.ndarray:
        target = self.vessel.poses(np.maximum(np.asarray(ts, dtype=float) - self.lag_s, self.t_start))
        yaw = np.arctan2(target[:, 1, 0], target[:, 0, 0])
        c, s = np.cos(yaw), np.sin(yaw)
        xy = target[:, :2, 3] + np.stack([-self.distance_m * c - self.lateral_m * s, -self.distance_m * s + self.lateral_m * c], axis=-1)
        return level_poses(xy, yaw)


@dataclass(eq=False)
class Mover:
    """A rigid moving object: `mesh` in its body frame, its `material`, and `motion.poses(ts)` world<-body."""

    id: str
    mesh: trimesh.Trimesh
    material: Material
    motion: Motion
    _facades: dict[float, FacadeIndex] = field(default_factory=dict, init=False, repr=False)

    def poses(self, ts: np.ndarray) -> np.ndarray:
        """(N, 4, 4) world<-body at times ts."""
        return self.motion.poses(np.atleast_1d(np.asarray(ts, dtype=float)))

    @cached_property
    def sphere(self) -> tuple[np.ndarray, float]:
        """Bounding sphere in the body frame: centre (3,) (of the bounding box) and radius."""
        centre = np.asarray(self.mesh.bounds, dtype=float).mean(axis=0)
        return centre, float(np.linalg.norm(np.asarray(self.mesh.vertices) - centre, axis=1).max())

    @cached_property
    def scene(self) -> o3d.t.geometry.RaycastingScene:
        """Open3D scene of the body-frame mesh, built once: rays are brought into the body frame instead."""
        scene = o3d.t.geometry.RaycastingScene()
        scene.add_triangles(
            o3d.core.Tensor(np.asarray(self.mesh.vertices, dtype=np.float32)), o3d.core.Tensor(np.asarray(self.mesh.faces, dtype=np.uint32))
        )
        return scene

    def cast(self, origins: np.ndarray, directions: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Distance (N,) to the body along body-frame rays (inf: missed) and the body-frame normals (N, 3) hit."""
        rays = np.concatenate([origins, directions], axis=1).astype(np.float32)
        hit = self.scene.cast_rays(o3d.core.Tensor(rays))
        return hit["t_hit"].numpy(), hit["primitive_normals"].numpy()

    def reflections(self, pose: np.ndarray, antenna: np.ndarray, directions: np.ndarray, radius_m: float) -> Reflections:
        """GNSS facade reflections off the hull's and cabin's sides at `pose`, in the world frame (none unless the
        material reflects L1)."""
        if not self.material.gnss_reflective:
            return Reflections(np.zeros(0, dtype=np.intp), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
        if radius_m not in self._facades:
            normals = np.asarray(self.mesh.face_normals)
            keep = (np.abs(normals[:, 2]) < VERTICAL_NZ) & (np.asarray(self.mesh.area_faces) >= MIN_FACET_AREA_M2)
            self._facades[radius_m] = FacadeIndex(
                np.asarray(self.mesh.triangles)[keep], normals[keep], np.zeros(int(keep.sum()), dtype=bool), radius_m
            )
        rot, at = pose[:3, :3], pose[:3, 3]
        body = self._facades[radius_m].reflections(rot.T @ (antenna - at), directions @ rot)
        return Reflections(body.sat, body.point @ rot.T + at, body.normal @ rot.T, body.extra_m)
