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


class FacadeIndex:
    """Reflective vertical faces of a world on a 2-D grid; `near(xy)` returns those within `radius_m`.

    Each grid cell stores the faces whose horizontal footprint (a segment) comes within radius_m
    plus half the cell diagonal of the cell centre, so one dictionary look-up bounds the search.
    """

    def __init__(self, vertices: np.ndarray, normals: np.ndarray, two_sided: np.ndarray, radius_m: float,
                 cell_m: float | None = None):
        self.radius_m = float(radius_m)
        self.two_sided = np.asarray(two_sided, dtype=bool)
        self.cell_m = float(cell_m if cell_m is not None else max(self.radius_m / 4.0, 5.0))
        self.vertices = np.asarray(vertices, dtype=float).reshape(-1, 3, 3)
        self.normals = np.asarray(normals, dtype=float).reshape(-1, 3)
        self.offset = np.einsum("ij,ij->i", self.normals, self.vertices[:, 0])
        self.origin = self.vertices[:, 0]
        # In-face test by barycentric coordinates: u = w.a, v = w.b for w = P - v0 (dual basis of the edges).
        e1 = self.vertices[:, 1] - self.origin
        e2 = self.vertices[:, 2] - self.origin
        d11, d12, d22 = (np.einsum("ij,ij->i", x, y) for x, y in ((e1, e1), (e1, e2), (e2, e2)))
        den = d11 * d22 - d12 * d12
        self.dual_a = (d22[:, None] * e1 - d12[:, None] * e2) / den[:, None]
        self.dual_b = (d11[:, None] * e2 - d12[:, None] * e1) / den[:, None]
        self._cells = self._build_cells()

    @classmethod
    def from_world(cls, world, radius_m: float) -> "FacadeIndex":
        """Index the facades of a World (parts with gnss_reflective material, vertical faces).

        Faces of a closed (watertight) part reflect only on their outer side; faces of open sheets
        reflect on both sides.
        """
        mesh = world.mesh
        reflective = np.array([p.material.gnss_reflective for p in world.parts], dtype=bool)
        closed = np.array([p.mesh.is_watertight for p in world.parts], dtype=bool)
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
        cells: dict[tuple[int, int], list[int]] = {}
        reach = self.radius_m + self.cell_m * np.sqrt(0.5)
        xy = self.vertices[:, :, :2]
        for face, tri in enumerate(xy):
            # Footprint segment of a vertical triangle: its extreme points along the face direction.
            along = np.array([-self.normals[face, 1], self.normals[face, 0]])
            norm = np.linalg.norm(along)
            along = along / norm if norm > 0 else np.array([1.0, 0.0])
            proj = tri @ along
            a, b = tri[np.argmin(proj)], tri[np.argmax(proj)]
            lo = np.floor((np.minimum(a, b) - reach) / self.cell_m).astype(int)
            hi = np.floor((np.maximum(a, b) + reach) / self.cell_m).astype(int)
            ix, iy = np.meshgrid(np.arange(lo[0], hi[0] + 1), np.arange(lo[1], hi[1] + 1), indexing="ij")
            centres = (np.stack([ix.ravel(), iy.ravel()], axis=1) + 0.5) * self.cell_m
            ab = b - a
            span = float(ab @ ab)
            t = np.clip(((centres - a) @ ab) / span, 0.0, 1.0) if span > 0 else np.zeros(len(centres))
            dist = np.linalg.norm(centres - (a + t[:, None] * ab), axis=1)
            for cx, cy in zip(ix.ravel()[dist <= reach], iy.ravel()[dist <= reach]):
                cells.setdefault((int(cx), int(cy)), []).append(face)
        return {key: np.asarray(faces, dtype=np.intp) for key, faces in cells.items()}

    def near(self, xy: np.ndarray) -> np.ndarray:
        """Indices of facades that may lie within radius_m of the horizontal position xy."""
        return self._cells.get(self._cell_of(xy), np.zeros(0, dtype=np.intp))

    def reflections(self, antenna: np.ndarray, directions: np.ndarray, min_distance_m: float = 0.05) -> Reflections:
        """Image-method reflections of unit satellite `directions` (M, 3) into `antenna` (3,)."""
        faces = self.near(antenna)
        if len(faces) == 0 or len(directions) == 0:
            return _no_reflections()
        normal = self.normals[faces]
        signed = normal @ antenna - self.offset[faces]
        normal = normal * np.sign(signed)[:, None]  # towards the antenna
        dist = np.abs(signed)
        near = (dist > min_distance_m) & (dist <= self.radius_m) & ((signed > 0) | self.two_sided[faces])
        faces, normal, dist = faces[near], normal[near], dist[near]
        cos_in = directions @ normal.T  # (M, F): n.s
        sat, col = np.nonzero(cos_in > 1e-6)
        if len(sat) == 0:
            return _no_reflections()
        d, n, ns = dist[col], normal[col], cos_in[sat, col]
        point = antenna - 2.0 * d[:, None] * n + (d / ns)[:, None] * directions[sat]
        f = faces[col]
        w = point - self.origin[f]
        u = np.einsum("ij,ij->i", w, self.dual_a[f])
        v = np.einsum("ij,ij->i", w, self.dual_b[f])
        inside = (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1.0 + 1e-9)
        return Reflections(sat=sat[inside], point=point[inside], normal=n[inside], extra_m=2.0 * (d * ns)[inside])


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
