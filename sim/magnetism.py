"""The magnetic field a compass on the river sees: the Earth's (a fixed model value at the world's origin) plus
the field of the steel structures the Earth's field magnetises.

Steel in the Earth's field carries an induced dipole moment along that field. Its size follows the
magnetometer surveyors' rule of thumb (Breiner, "Applications Manual for Portable Magnetometers",
Geometrics, 1973/1999, and Geometrics' own statement of it): one tonne of steel gives about a 1 nT
anomaly at 30 m, linear in mass and falling off as the cube of distance, i.e. a moment of
1 nT x (30 m)^3 / (mu0 / 4 pi) = 270 A m^2 per tonne; hollow members (tubes, boxes) act as if solid,
and permanent (remanent) magnetisation can add a factor of 3-5. A world's steel parts (material
steel: girders, trusses, steel arch ribs, lock gates, steel piles) are cut into cells; each cell is
a dipole of its share of the part's steel mass (the part's mesh volume x 7850 kg/m^3, spread by
surface area), at the cell's centre. This is computed once per world; a field query sums the cells
within a cut-off radius (a KD-tree), so it is cheap at a compass's rate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

MU0_OVER_4PI = 1e-7
"""T m / A."""
STEEL_DENSITY = 7850.0
"""kg/m^3 (structural steel, EN 1991-1-1 Table A.4)."""
MOMENT_PER_TONNE = 1e-9 * 30.0**3 / MU0_OVER_4PI
"""A m^2 per tonne of steel: 1 nT at 30 m (Breiner's rule of thumb)."""


def earth_field_enu(declination_deg: float, inclination_deg: float, intensity_ut: float) -> np.ndarray:
    """The main field in the local ENU frame, microtesla: horizontal part towards magnetic north (declination east
    of true north positive), inclination positive downward."""
    d, i = math.radians(declination_deg), math.radians(inclination_deg)
    h = intensity_ut * math.cos(i)
    return np.array([h * math.sin(d), h * math.cos(d), -intensity_ut * math.sin(i)])


def dipole_field_ut(points: np.ndarray, positions: np.ndarray, moments: np.ndarray, min_range_m: float) -> np.ndarray:
    """Field (N, 3) in microtesla at points (N, 3) of dipoles at positions (M, 3) with moments (M, 3) A m^2:
    mu0/4pi (3 (m.r) r / r^5 - m / r^3), every distance taken as at least min_range_m (a dipole stands for a cell of steel)."""
    r = points[:, None, :] - positions[None, :, :]
    dist = np.maximum(np.linalg.norm(r, axis=-1), min_range_m)
    m_dot_r = np.einsum("nmi,mi->nm", r, moments)
    field = 3.0 * m_dot_r[..., None] * r / dist[..., None] ** 5 - moments[None] / dist[..., None] ** 3
    return MU0_OVER_4PI * 1e6 * field.sum(axis=1)


@dataclass
class SteelField:
    """Dipoles standing for the world's steel: positions (M, 3) ENU m, moments (M, 3) A m^2, masses (M,) t. `field_ut(points)`."""

    positions: np.ndarray
    moments: np.ndarray
    masses: np.ndarray
    cell_m: float = 2.0
    cutoff_m: float = 250.0

    def __post_init__(self) -> None:
        self._tree = cKDTree(self.positions) if len(self.positions) else None

    @property
    def tonnes(self) -> float:
        return float(self.masses.sum())

    def field_ut(self, points: np.ndarray) -> np.ndarray:
        """The steel's field (N, 3), microtesla, at ENU points (N, 3); cells beyond cutoff_m are left out."""
        points = np.atleast_2d(np.asarray(points, dtype=float))
        out = np.zeros((len(points), 3))
        if self._tree is None:
            return out
        near = self._tree.query_ball_point(points, self.cutoff_m)
        for i, cells in enumerate(near):
            if cells:
                idx = np.asarray(cells)
                out[i] = dipole_field_ut(points[i : i + 1], self.positions[idx], self.moments[idx], self.cell_m)[0]
        return out


def steel_field(world, direction: np.ndarray, moment_per_tonne: float = MOMENT_PER_TONNE, cell_m: float = 2.0, cutoff_m: float = 250.0) -> SteelField:
    """The induced dipoles of `world`'s steel parts in cells of cell_m, moments along `direction` (the Earth field's unit vector)."""
    centres, masses = [], []
    for part in world.parts:
        if part.material.name != "steel":
            continue
        mesh = part.mesh
        tonnes = abs(float(mesh.volume)) * STEEL_DENSITY / 1000.0
        area = np.asarray(mesh.area_faces, dtype=float)
        if tonnes <= 0 or area.sum() <= 0:
            continue
        centres.append(np.asarray(mesh.triangles_center, dtype=float))
        masses.append(tonnes * area / area.sum())
    if not centres:
        return SteelField(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), cell_m, cutoff_m)
    pos, mass = np.concatenate(centres), np.concatenate(masses)
    keys = np.floor(pos / cell_m).astype(np.int64)
    _, cell, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    cell = cell.ravel()
    cell_mass = np.bincount(cell, weights=mass, minlength=len(counts))
    cell_pos = np.stack([np.bincount(cell, weights=mass * pos[:, k], minlength=len(counts)) for k in range(3)], axis=1) / cell_mass[:, None]
    moments = moment_per_tonne * cell_mass[:, None] * np.asarray(direction, dtype=float)[None, :]
    return SteelField(cell_pos, moments, cell_mass, cell_m, cutoff_m)
