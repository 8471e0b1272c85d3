"""Where scattered objects (buildings, trees, boats, docks) may go: the channel edge, the route and solids.

Checks shared by the builders that place things beside or on the river: signed distance from the
channel edge (land or water side), horizontal distance from the route the vessel follows, and
distance from the solid structures already built (bridges, locks, buildings).
"""

from __future__ import annotations

from typing import cast

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from worlds.channel import Centerline
from worlds.geometry import untangle
from worlds.route import Route
from worlds.world import Part

SOLID_KINDS = ("bridge_deck", "pier", "girder", "arch", "lock_wall", "lock_gate", "building")
"""Structures nothing else may overlap."""


def edge(line: Centerline, side: str) -> tuple[np.ndarray, np.ndarray]:
    """The channel edge on `side` (loops trimmed) every ~4 m, and its outward normals."""
    xy, nl = line.xy[::4], np.stack([-np.sin(line.heading[::4]), np.cos(line.heading[::4])], 1)
    out = line.side_sign(side) * nl
    return untangle(xy + out * line.width(side)[::4, None]), out


def clearance(edge_line: tuple[np.ndarray, np.ndarray], pts: np.ndarray) -> np.ndarray:
    """Distance of each point from the channel edge; negative when on the water side of it."""
    edge_xy, out = edge_line
    d = np.linalg.norm(pts[:, None, :] - edge_xy[None, :, :], axis=2)
    k = d.argmin(axis=1)
    side = np.sign(np.einsum("ij,ij->i", pts - edge_xy[k], out[k]))
    return d[np.arange(len(pts)), k] * side


class Edges:
    """Both channel edges of a centreline, untangled once, for many `clearance` queries."""

    def __init__(self, line: Centerline):
        self._edges = {side: edge(line, side) for side in ("left", "right")}

    def clearance(self, side: str, pts: np.ndarray) -> np.ndarray:
        """`clearance` from the edge on `side` (negative on the water side)."""
        return clearance(self._edges[side], pts) if len(pts) else np.zeros(0)


class RouteDistance:
    """Horizontal distance from points to the route polyline (resampled every 0.25 m: error < 1 cm)."""

    def __init__(self, route: Route):
        s = np.arange(0.0, route.length + 0.25, 0.25)
        self._tree = cKDTree(route.at(s)[0])

    def __call__(self, xy: np.ndarray) -> np.ndarray:
        return self._tree.query(np.asarray(xy, dtype=float)[:, :2])[0]


class SolidDistance:
    """Distance from points to the parts of `kinds` among `parts`: 0 inside a closed one, inf when there are none."""

    def __init__(self, parts: list[Part], kinds: tuple[str, ...] = SOLID_KINDS):
        solid = [p.mesh for p in parts if p.kind in kinds]
        self._surface = _scene(solid)
        # inside/outside by ray parity is only meaningful for closed meshes (boxes, piers), not open vaults
        self._closed = _scene([m for m in solid if m.is_watertight])

    def __call__(self, points: np.ndarray) -> np.ndarray:
        import open3d as o3d

        points = np.asarray(points, dtype=np.float32).reshape(-1, 3)
        if self._surface is None or not len(points):
            return np.full(len(points), np.inf)
        query = o3d.core.Tensor(points)
        dist = self._surface.compute_distance(query).numpy()
        if self._closed is not None:
            dist[self._closed.compute_occupancy(query).numpy() > 0] = 0.0
        return dist


def _scene(meshes: list[trimesh.Trimesh]):
    import open3d as o3d

    if not meshes:
        return None
    mesh = cast(trimesh.Trimesh, trimesh.util.concatenate(meshes))  # meshes in, a mesh out
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(np.asarray(mesh.vertices, np.float32)), o3d.core.Tensor(np.asarray(mesh.faces, np.uint32)))
    return scene
