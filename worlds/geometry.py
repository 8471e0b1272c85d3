"""Mesh primitives the builders share: swept strips, offset curves without loops, boxes, pipes."""

from __future__ import annotations

import numpy as np
import trimesh

UP = np.array([0.0, 0.0, 1.0])


def strip(lines: np.ndarray) -> trimesh.Trimesh:
    """Triangulate the quads between P polylines of N points each, `lines` shaped (P, N, 3).

    Degenerate triangles (from collapsed offset points) are dropped.
    """
    lines = np.asarray(lines, dtype=float)
    n_lines, n_pts = lines.shape[:2]
    idx = np.arange(n_lines * n_pts).reshape(n_lines, n_pts)
    a, b = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel()
    c, d = idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return mesh_from(lines.reshape(-1, 3), faces)


def mesh_from(vertices: np.ndarray, faces: np.ndarray) -> trimesh.Trimesh:
    """A Trimesh of the given triangles minus zero-area ones, without trimesh's merging passes."""
    vertices = np.asarray(vertices, dtype=float)
    faces = np.asarray(faces, dtype=np.int64)
    tri = vertices[faces]
    area2 = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    return trimesh.Trimesh(vertices, faces[area2 > 1e-9], process=False)


def orient(mesh: trimesh.Trimesh, toward: np.ndarray) -> trimesh.Trimesh:
    """Flip faces so each face normal has a non-negative component along `toward` ((3,) or (F, 3))."""
    faces = np.asarray(mesh.faces).copy()
    tri = np.asarray(mesh.vertices)[faces]
    normal = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    flip = np.einsum("ij,ij->i", normal, np.broadcast_to(toward, normal.shape)) < 0
    faces[flip] = faces[flip][:, ::-1]
    return trimesh.Trimesh(mesh.vertices, faces, process=False)


def untangle(pts: np.ndarray) -> np.ndarray:
    """Trim the loops of an offset curve, keeping one point per station.

    On the inner side of a bend whose radius is below the offset, the raw offset curve crosses
    itself and loops back. For every crossing of segments i and j (outermost first), the points
    i+1..j of the loop are all moved onto the crossing point, which is the trimmed curve with
    zero-length steps (the degenerate quads they make are dropped by `strip`).
    """
    pts = np.asarray(pts, dtype=float)
    a, d = pts[:-1], np.diff(pts, axis=0)
    n = len(a)
    hits: list[tuple[int, int, np.ndarray]] = []
    for start in range(0, n, 512):
        rows = np.arange(start, min(start + 512, n))
        ai, di = a[rows][:, None, :], d[rows][:, None, :]
        rel = a[None, :, :] - ai
        den = di[..., 0] * d[None, :, 1] - di[..., 1] * d[None, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (rel[..., 0] * d[None, :, 1] - rel[..., 1] * d[None, :, 0]) / den
            u = (rel[..., 0] * di[..., 1] - rel[..., 1] * di[..., 0]) / den
        cross = (np.abs(den) > 1e-12) & (t >= 0) & (t < 1) & (u >= 0) & (u < 1)
        cross &= np.arange(n)[None, :] > rows[:, None] + 1
        for ii, jj in zip(*np.nonzero(cross)):
            k = rows[ii]
            hits.append((int(k), int(jj), pts[k] + t[ii, jj] * d[k]))
    out = pts.copy()
    done = -1
    for i, j, x in sorted(hits, key=lambda h: (h[0], -h[1])):
        if i < done:
            continue
        out[i + 1 : j + 1] = x
        done = j
    return out


def box(center: np.ndarray, x_axis: np.ndarray, size: tuple[float, float, float]) -> trimesh.Trimesh:
    """Box of `size` (along x_axis, along the horizontal perpendicular, along z) centred at `center`.

    x_axis is a horizontal direction (2-D or 3-D); the box stays upright so its sides are vertical.
    """
    ux = np.r_[np.asarray(x_axis, float)[:2], 0.0]
    ux /= np.linalg.norm(ux)
    uy = np.cross(UP, ux)
    transform = np.eye(4)
    transform[:3, 0], transform[:3, 1], transform[:3, 2] = ux, uy, UP
    transform[:3, 3] = center
    return trimesh.creation.box(extents=size, transform=transform)


def pipe(a: np.ndarray, b: np.ndarray, radius: float, sections: int = 6) -> trimesh.Trimesh:
    """Open-ended thin cylinder (girder member, pipe) from point a to point b."""
    return trimesh.creation.cylinder(radius=radius, segment=np.array([a, b], float), sections=sections)


def merge(meshes: list[trimesh.Trimesh]) -> trimesh.Trimesh:
    """Concatenate meshes into one (no vertex merging, so faces stay exactly as built)."""
    vertices, faces, offset = [], [], 0
    for m in meshes:
        vertices.append(np.asarray(m.vertices, float))
        faces.append(np.asarray(m.faces, np.int64) + offset)
        offset += len(m.vertices)
    return trimesh.Trimesh(np.concatenate(vertices), np.concatenate(faces), process=False)


def adaptive_indices(heading: np.ndarray, s: np.ndarray, max_turn_rad: float, max_step_m: float) -> np.ndarray:
    """Indices of route vertices to keep: a new one whenever the heading turned max_turn_rad or
    max_step_m was travelled since the last kept one (coarse on straights, dense in bends)."""
    keep = [0]
    for i in range(1, len(s) - 1):
        j = keep[-1]
        if abs(heading[i] - heading[j]) >= max_turn_rad or s[i] - s[j] >= max_step_m:
            keep.append(i)
    keep.append(len(s) - 1)
    return np.asarray(keep)
