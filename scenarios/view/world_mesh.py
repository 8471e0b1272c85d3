"""The world as the viewer draws it: each part's mesh coloured by its material, the largest decimated to a triangle budget.

Logged once, as static data: its size is paid once per recording, not per scan. The budget keeps that a
few MB (charles_river has 246k triangles, 174k of them one part: the tree crowns).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d

MAX_TRIANGLES = 150_000
"""Triangles of the whole world in the view; parts above a common cap are decimated to it (quadric error, Open3D)."""

MATERIAL_COLOURS: dict[str, tuple[int, int, int]] = {
    "water": (40, 90, 160),
    "concrete": (170, 170, 165),
    "granite": (130, 130, 135),
    "brick": (150, 80, 60),
    "steel": (90, 95, 105),
    "glass": (150, 190, 210),
    "timber": (120, 85, 50),
    "grass": (95, 145, 65),
    "soil": (115, 95, 70),
    "vegetation": (55, 115, 50),
    "fibreglass": (230, 230, 225),
    "aluminium": (190, 195, 200),
}
"""Albedo of each of worlds.materials' materials (sRGB); a material not listed (a plugin world's) is drawn grey."""
OTHER_COLOUR = (160, 160, 160)


@dataclass(frozen=True)
class PartMesh:
    """One part as drawn: vertices (V, 3) and vertex normals (V, 3) in world ENU, faces (F, 3), an sRGB albedo."""

    name: str
    kind: str
    vertices: np.ndarray
    normals: np.ndarray
    faces: np.ndarray
    colour: tuple[int, int, int]


def triangle_cap(counts: list[int], budget: int) -> int:
    """The largest cap c with sum(min(n, c)) <= budget (every part keeps up to c triangles); no cap when all fit."""
    total = sum(counts)
    if total <= budget:
        return max(counts, default=0)
    below = 0  # triangles of the parts under the cap
    ordered = sorted(counts)
    for i, n in enumerate(ordered):
        cap = (budget - below) // (len(ordered) - i)  # the rest share what is left equally
        if cap < n:
            return max(cap, 1)
        below += n
    return ordered[-1]


def part_meshes(world, budget: int = MAX_TRIANGLES) -> list[PartMesh]:
    """Every part of `world`, those above the common triangle cap decimated to it."""
    cap = triangle_cap([len(p.mesh.faces) for p in world.parts], budget)
    out = []
    for part in world.parts:
        vertices, faces = np.asarray(part.mesh.vertices), np.asarray(part.mesh.faces)
        if len(faces) > cap:
            vertices, faces, normals = _decimated(vertices, faces, cap)
        else:
            normals = np.asarray(part.mesh.vertex_normals)
        colour = MATERIAL_COLOURS.get(part.material.name, OTHER_COLOUR)
        out.append(PartMesh(part.name, part.kind, vertices, normals, faces, colour))
    return out


def _decimated(vertices: np.ndarray, faces: np.ndarray, target: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Quadric-error decimation to about `target` triangles: vertices, faces, vertex normals."""
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(vertices), o3d.utility.Vector3iVector(faces.astype(np.int32)))
    mesh = mesh.simplify_quadric_decimation(target_number_of_triangles=int(target)).remove_unreferenced_vertices()
    mesh.compute_vertex_normals()
    return np.asarray(mesh.vertices), np.asarray(mesh.triangles), np.asarray(mesh.vertex_normals)
