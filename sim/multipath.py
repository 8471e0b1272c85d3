"""GNSS multipath off facades: a spatial index of reflective vertical faces and the image method.

A facade is a face of the world mesh that is (near) vertical and belongs to a part whose material
reflects L1 signals (walls, quays, lock walls, buildings, ...). For an antenna A at distance d in
front of a facade plane with unit normal n (pointing towards A) and a satellite in direction s
(unit, far away), the mirror image of A is A' = A - 2 d n; the reflected signal leaves the plane at
P = A' + (d / n.s) s and travels 2 d (n.s) further than a direct one (2 d sin of the grazing
angle; for a vertical facade n.s = cos(el) cos(az - az_n)). The reflection exists when n.s > 0
and P lies inside the face; whether both legs are unobstructed is for the ray caster to decide.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

L1_WAVELENGTH_M = 299_792_458.0 / 1575.42e6
"""GPS L1 carrier wavelength, ~0.1903 m."""
CA_CHIP_M = 299_792_458.0 / 1.023e6
"""Length of one C/A code chip, ~293.05 m."""
VERTICAL_NZ = 0.1
"""Faces with |n_z| below this (within ~6 deg of vertical) count as facades."""
MIN_FACET_AREA_M2 = 1.0
"""Smaller faces (truss members, pipes, tessellated curves) scatter diffusely rather than reflect
specularly: the first Fresnel zone of an L1 reflection at 10-50 m is 1.4-3 m across."""


@dataclass(frozen=True)
class Reflections:
    """Candidate specular reflections: one row per (satellite, facade) pair that passed the geometry.

    sat: index into the satellite directions; point: (K, 3) reflection point on the facade;
    normal: (K, 3) facade normal towards the antenna; extra_m: (K,) extra path length.
    """

    sat: np.ndarray
    point: np.ndarray
    normal: np.ndarray
    extra_m: np.ndarray

    def __len__(self) -> int:
        return len(self.sat)

    def joined(self, other: Reflections) -> Reflections:
        """These candidates followed by `other`'s."""
        return Reflections(
            np.concatenate([self.sat, other.sat]),
            np.concatenate([self.point, other.point]),
            np.concatenate([self.normal, other.normal]),
            np.concatenate([self.extra_m, other.extra_m]),
        )


class FacadeIndex:
    """Reflective vertical faces of a world on a 2-D grid; `near(xy)` returns those within `radius_m`.

    Each grid cell stores the faces whose horizontal footprint (a segment) comes within radius_m
    plus half the cell diagonal of the cell centre, so one dictionary look-up bounds the search.
    """

    def __init__(self, vertices: np.ndarray, normals: np.ndarray, two_sided: np.ndarray, radius_m: float, cell_m: float | None = None):
        self.radius_m = float(radius_m)
        self.two_sided = np.asarray(two_sided, dtype=bool)
        self.cell_m = float(cell_m if cell_m is not None else max(self.radius_m / 4.0, 5.0))
        self.vertices = np.asarray(vertices, dtype=float).reshape(-1, 3, 3)
        self.normals = np.asarray(normals, dtype=float).reshape(-1, 3)
        self.origin = self.vertices[:, 0]
        # In-plane basis per face: t horizontal, b = n x t (up the face); the in-face test solves
        # P - v0 = u e1 + v e2 in (t, b) coordinates with the inverse of [e1 e2] precomputed.
        t = np.stack([-self.normals[:, 1], self.normals[:, 0], np.zeros(len(self.normals))], axis=1)
        self.tangent = t / np.linalg.norm(t, axis=1, keepdims=True)
        self.bitangent = np.cross(self.normals, self.tangent)
        e1 = self.vertices[:, 1] - self.origin
        e2 = self.vertices[:, 2] - self.origin
        e1t, e1b = np.einsum("ij,ij->i", e1, self.tangent), np.einsum("ij,ij->i", e1, self.bitangent)
        e2t, e2b = np.einsum("ij,ij->i", e2, self.tangent), np.einsum("ij,ij->i", e2, self.bitangent)
        det = e1t * e2b - e2t * e1b
        self.to_u = np.stack([e2b, -e2t], axis=1) / det[:, None]
        self.to_v = np.stack([-e1b, e1t], axis=1) / det[:, None]
        # Everything a query needs per face in one row, so a query gathers once.
        self._rows = np.hstack([self.origin, self.normals, self.tangent, self.bitangent, self.to_u, self.to_v, self.two_sided[:, None]])
        self._cells = self._build_cells()

    @classmethod
    def from_world(cls, world, radius_m: float) -> FacadeIndex:
        """Index the facades of a World (parts with gnss_reflective material, vertical faces).

        Faces of a closed (watertight) part reflect only on their outer side; faces of open sheets
        reflect on both sides.
        """
        mesh = world.mesh
        reflective = np.array([p.material.gnss_reflective for p in world.parts], dtype=bool)
        closed = np.array([p.material.gnss_reflective and p.mesh.is_watertight for p in world.parts], dtype=bool)  # others are never kept
        normals = np.asarray(mesh.face_normals)
        keep = reflective[world.face_part] & (np.abs(normals[:, 2]) < VERTICAL_NZ)
        keep &= np.asarray(mesh.area_faces) >= MIN_FACET_AREA_M2
        two_sided = ~closed[world.face_part[keep]]
        return cls(np.asarray(mesh.triangles)[keep], normals[keep], two_sided, radius_m)

    def __len__(self) -> int:
        return len(self.normals)

    def _cell_of(self, xy: np.ndarray) -> tuple[int, int]:
        return int(np.floor(xy[0] / self.cell_m)), int(np.floor(xy[1] / self.cell_m))

    def _build_cells(self) -> dict[tuple[int, int], np.ndarray]:
        """Cell -> faces (ascending) whose footprint segment passes within radius_m + half a cell diagonal of its centre.

        All (face, cell) candidates of every face's bounding box at once: each face's box is enumerated row-major
        (x index major) from a flat counter, as a per-face meshgrid would.
        """
        reach = self.radius_m + self.cell_m * np.sqrt(0.5)
        xy = self.vertices[:, :, :2]
        # Footprint segment of a vertical triangle: its extreme points along the face direction.
        along = np.stack([-self.normals[:, 1], self.normals[:, 0]], axis=1)
        norm = np.linalg.norm(along, axis=1)
        flat = norm == 0
        along = np.where(flat[:, None], np.array([1.0, 0.0]), along / np.where(flat, 1.0, norm)[:, None])
        proj = np.einsum("fvk,fk->fv", xy, along)
        faces = np.arange(len(xy))
        a, b = xy[faces, np.argmin(proj, axis=1)], xy[faces, np.argmax(proj, axis=1)]
        lo = np.floor((np.minimum(a, b) - reach) / self.cell_m).astype(int)
        hi = np.floor((np.maximum(a, b) + reach) / self.cell_m).astype(int)
        size = hi - lo + 1
        count = size[:, 0] * size[:, 1]
        face = np.repeat(faces, count)
        local = np.arange(count.sum()) - np.repeat(np.cumsum(count) - count, count)
        ix = lo[face, 0] + local // size[face, 1]
        iy = lo[face, 1] + local % size[face, 1]
        centres = (np.stack([ix, iy], axis=1) + 0.5) * self.cell_m
        ab = b - a
        span = np.einsum("fk,fk->f", ab, ab)
        rel = centres - a[face]
        along_ab = np.einsum("ck,ck->c", rel, ab[face])
        positive = span[face] > 0
        t = np.where(positive, np.clip(along_ab / np.where(positive, span[face], 1.0), 0.0, 1.0), 0.0)
        dist = np.linalg.norm(centres - (a[face] + t[:, None] * ab[face]), axis=1)
        near = dist <= reach
        if not near.any():
            return {}
        face, ix, iy = face[near], ix[near], iy[near]
        order = np.lexsort((face, iy, ix))
        face, ix, iy = face[order], ix[order], iy[order]
        starts = np.flatnonzero(np.r_[True, (ix[1:] != ix[:-1]) | (iy[1:] != iy[:-1])])
        return {(int(ix[s]), int(iy[s])): group for s, group in zip(starts, np.split(face.astype(np.intp), starts[1:]))}

    def near(self, xy: np.ndarray) -> np.ndarray:
        """Indices of facades that may lie within radius_m of the horizontal position xy."""
        return self._cells.get(self._cell_of(xy), np.zeros(0, dtype=np.intp))

    def reflections(self, antenna: np.ndarray, directions: np.ndarray, min_distance_m: float = 0.05) -> Reflections:
        """Image-method reflections of unit satellite `directions` (M, 3) into `antenna` (3,).

        Works on (satellite x facade) matrices in each facade's plane coordinates: the reflection
        point is P = v0 + p_t t + p_b b with (p_t, p_b) = (a_t, a_b) + (d / n.s) (s.t, s.b).
        """
        faces = self.near(antenna)
        if len(faces) == 0 or len(directions) == 0:
            return _no_reflections()
        rows = self._rows[faces]
        rel = antenna - rows[:, 0:3]
        signed = np.einsum("ij,ij->i", rel, rows[:, 3:6])
        dist = np.abs(signed)
        keep = (dist > min_distance_m) & (dist <= self.radius_m) & ((signed > 0) | (rows[:, 16] > 0))
        if not keep.any():
            return _no_reflections()
        rows, rel, signed, dist = rows[keep], rel[keep], signed[keep], dist[keep]
        normal = rows[:, 3:6] * np.sign(signed)[:, None]  # towards the antenna
        t, b = rows[:, 6:9], rows[:, 9:12]
        ns = directions @ normal.T  # (M, F)
        with np.errstate(divide="ignore", invalid="ignore"):
            k = dist / ns
        p_t = np.einsum("ij,ij->i", rel, t) + k * (directions @ t.T)
        p_b = np.einsum("ij,ij->i", rel, b) + k * (directions @ b.T)
        u = p_t * rows[:, 12] + p_b * rows[:, 13]
        v = p_t * rows[:, 14] + p_b * rows[:, 15]
        sat, col = np.nonzero((ns > 1e-6) & (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1.0 + 1e-9))
        point = rows[col, 0:3] + p_t[sat, col, None] * t[col] + p_b[sat, col, None] * b[col]
        return Reflections(sat=sat, point=point, normal=normal[col], extra_m=2.0 * dist[col] * ns[sat, col])


def _no_reflections() -> Reflections:
    return Reflections(np.zeros(0, dtype=np.intp), np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))


def code_multipath_error(extra_m: np.ndarray, amplitude: float, spacing_chips: float, phase: np.ndarray) -> np.ndarray:
    """Code tracking error (m) of an early-minus-late DLL with `spacing_chips` from one reflection.

    The reflection has relative amplitude `amplitude` (< 1), extra delay `extra_m` and carrier
    phase `phase` (rad) relative to the direct signal; with c = amplitude*cos(phase), spacing d and
    delay x in chips, the zero of the coherent discriminator on the triangular C/A correlation is
    c*x/(1+c) for x < (1+c)d/2, c*d/2 up to x = 1-(1-c)d/2, then c*(1+d/2-x)/(2-c) falling to 0
    at x = 1+d/2: the classic multipath error envelope (its extremes at cos(phase) = +-1).
    """
    x = np.asarray(extra_m, dtype=float) / CA_CHIP_M
    d = spacing_chips
    c = amplitude * np.cos(phase)
    error = np.where(
        x < (1.0 + c) * d / 2.0,
        c * x / (1.0 + c),
        np.where(x < 1.0 - (1.0 - c) * d / 2.0, c * d / 2.0, c * (1.0 + d / 2.0 - x) / (2.0 - c)),
    )
    return np.where(x < 1.0 + d / 2.0, error, 0.0) * CA_CHIP_M
