"""Hull clearance: the distance from the vessel's body to the nearest structure, and contact.

The hull (pontoons and tray, without the mast) is sampled evenly on its surface; the distance of
those points to every world part that reaches down into the hull's height band (Open3D's Embree
closest-point query, in one batch) is the clearance. Parts entirely above the band (bridge decks,
girders) are overhead: the air draft under them is not a clearance to a pier or a wall, and
would otherwise cap every clearance under a bridge. Contact (a collision) is a clearance at or
below `contact_m`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d
import trimesh

HULL_SAMPLES = 600
"""Points on the hull's surface (every ~0.15 m on a 4.9 x 2.4 m WAM-V)."""


@dataclass(frozen=True)
class Clearance:
    """Distance (m) from the hull to the nearest structure and the index of that world part (-1: none in the world)."""

    distance_m: float
    part: int


class HullClearance:
    """`at(poses)`: the clearance of the hull at world<-base_link poses, vectorised.

    hull: the body in base_link (sim.vessel.hull_mesh without the mast); parts whose lowest point
    is more than `headroom_m` above its top are overhead and left out.
    """

    def __init__(self, world, hull: trimesh.Trimesh, contact_m: float = 0.05, headroom_m: float = 0.5):
        self.contact_m = contact_m
        band_top = float(hull.bounds[1, 2]) + headroom_m
        solid = [i for i, p in enumerate(world.parts) if not p.material.water and p.mesh.bounds[0, 2] < band_top]
        self.scene = o3d.t.geometry.RaycastingScene()
        self._part_of_geometry: dict[int, int] = {}
        for i in solid:
            mesh = world.parts[i].mesh
            gid = self.scene.add_triangles(
                o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)), o3d.core.Tensor(np.asarray(mesh.faces, dtype=np.uint32))
            )
            self._part_of_geometry[gid] = i
        self._empty = not solid
        self.samples = np.asarray(trimesh.sample.sample_surface_even(hull, HULL_SAMPLES, seed=0)[0], dtype=float)

    def at(self, poses: np.ndarray) -> list[Clearance]:
        """Clearance at each (N, 4, 4) pose (or one 4x4)."""
        poses = np.asarray(poses, dtype=float).reshape(-1, 4, 4)
        if self._empty:
            return [Clearance(np.inf, -1)] * len(poses)
        pts = np.einsum("nij,mj->nmi", poses[:, :3, :3], self.samples) + poses[:, None, :3, 3]
        query = o3d.core.Tensor(pts.reshape(-1, 3).astype(np.float32))
        closest = self.scene.compute_closest_points(query)
        d = np.linalg.norm(closest["points"].numpy() - query.numpy(), axis=1).reshape(len(poses), -1)
        gid = closest["geometry_ids"].numpy().reshape(len(poses), -1)
        nearest = np.argmin(d, axis=1)
        return [Clearance(float(d[k, j]), self._part_of_geometry.get(int(gid[k, j]), -1)) for k, j in enumerate(nearest)]

    def touching(self, clearance: Clearance) -> bool:
        """The hull is in contact with (or inside) a structure."""
        return clearance.distance_m <= self.contact_m
