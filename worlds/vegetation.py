"""Trees on the banks: a solid trunk and a porous crown of many small, randomly tilted facets.

A crown is an upright spheroid filled with equilateral facets at random positions and orientations,
`leaf_density` m^2 of facet per m^3 of crown. A ray crossing a length L of crown meets facets at a
rate of density/2 per metre (the mean projected area of a randomly oriented facet is half its area),
so it passes through with probability exp(-density * L / 2) (0.17 through the middle of a 10 m
crown at 0.35 m^2/m^3) and its returns have noisy normals, as laser returns from foliage do. Every
facet lies inside its crown's envelope (`Crowns`), which GNSS uses for foliage attenuation. Trunks
are solids (they block GNSS like a pier would); only crowns are porous.
Every draw comes from `riverbench.rng.stream(seed, "worlds.vegetation")`.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field, model_validator

from riverbench.rng import stream
from worlds.channel import Centerline, ChannelParams, ground_height
from worlds.crowns import Crowns
from worlds.materials import TIMBER, VEGETATION
from worlds.placement import Edges, RouteDistance, SolidDistance
from worlds.world import Part

TRUNK_SECTIONS = 6
LEAF_PROJECTION = 0.5
"""Mean projected area of a randomly oriented leaf per unit of its area (Ross's G-function for a spherical leaf angle
distribution, Ross 1981): a ray meets leaves at leaf_density x this per metre of crown."""
SMALL_CROWN_FACET = 0.35
"""Facets are at most this share of a crown's smaller radius: small crowns get finer leaf clusters."""


class TreeRow(BaseModel):
    """Trees along one side of the route between two stations; a wide setback range makes a grove."""

    model_config = ConfigDict(extra="forbid")

    side: Literal["left", "right"] = Field(..., description="side of the route, looking along it")
    start_m: float = Field(..., description="route station where the row starts, m")
    end_m: float = Field(..., description="route station where the row ends, m")
    setback_m: tuple[float, float] = Field((3.0, 8.0), description="range of trunk distances from the channel edge onto land, m")
    spacing_m: tuple[float, float] = Field((8.0, 14.0), description="range of along-route distances between neighbouring trees, m")
    height_m: tuple[float, float] = Field((12.0, 20.0), description="range of tree heights above the ground, m")
    crown_radius_m: tuple[float, float] = Field((3.0, 6.0), description="range of horizontal crown radii, m")
    crown_base: tuple[float, float] = Field(
        (0.25, 0.35),
        description="range of the share of the height where the crown starts (clear trunk below; ~0.1 for willows hanging down to the ground)",
    )

    @model_validator(mode="after")
    def _ranges(self) -> TreeRow:
        for key in ("setback_m", "spacing_m", "height_m", "crown_radius_m", "crown_base"):
            lo, hi = getattr(self, key)
            if not 0.0 < lo <= hi or (key == "crown_base" and hi >= 0.9):
                raise ValueError(f"{key}: need 0 < min <= max{' < 0.9' if key == 'crown_base' else ''}, got ({lo}, {hi})")
        if self.end_m <= self.start_m:
            raise ValueError(f"end_m={self.end_m} must be greater than start_m={self.start_m}")
        return self


class Foliage(BaseModel):
    """How crowns are filled."""

    model_config = ConfigDict(extra="forbid")

    leaf_density: float = Field(0.35, gt=0.0, le=3.0, description="facet area per crown volume, m^2/m^3 (0.35: 17% of rays cross a 10 m crown)")
    facet_m: float = Field(1.5, ge=0.2, le=3.0, description="side of the equilateral foliage facets (leaf clusters), m")


def build_trees(
    rows: list[TreeRow],
    line: Centerline,
    edges: Edges,
    channel: ChannelParams,
    seed: int,
    density: float,
    foliage: Foliage,
    route_distance: RouteDistance,
    solids: SolidDistance,
    clearance_m: float,
) -> tuple[list[Part], Crowns]:
    """Trunk and crown parts of every tree that stands on land, keeps `clearance_m` from the route
    with its crown, and touches no solid structure; and the crowns' envelopes."""
    rng = stream(seed, "worlds.vegetation")
    trees = [_place(row, line, edges, channel, rng, density) for row in rows]
    base, height, radius, trunk_r, crown_h = (np.concatenate([t[k] for t in trees] + [np.zeros((0, 3) if k == 0 else 0)]) for k in range(5))
    centre = base + np.c_[np.zeros((len(base), 2)), height - crown_h]
    reach = np.maximum(radius, crown_h)
    trunk_mid = base + np.c_[np.zeros((len(base), 2)), 0.5 * (height - crown_h)]
    ok = route_distance(centre) - radius >= clearance_m
    ok &= solids(centre) > reach
    ok &= solids(trunk_mid) > 0.5 * (height - crown_h) + trunk_r
    base, height, radius, trunk_r, centre, crown_h = base[ok], height[ok], radius[ok], trunk_r[ok], centre[ok], crown_h[ok]
    if not len(base):
        return [], Crowns.empty()
    crowns = Crowns(centre, np.c_[radius, crown_h], np.full(len(centre), foliage.leaf_density * LEAF_PROJECTION))
    trunks = _trunks(base, centre[:, 2], trunk_r)
    return [Part("tree_trunks", "tree", TIMBER, trunks), Part("tree_crowns", "foliage", VEGETATION, _facets(crowns, foliage, rng))], crowns


def _place(row: TreeRow, line: Centerline, edges: Edges, channel: ChannelParams, rng: np.random.Generator, density: float):
    """Candidate trees of one row: base point (ground under the trunk), height, crown radius, trunk radius,
    crown half-height."""
    start, end = max(row.start_m, float(line.s[0])), min(row.end_m, float(line.s[-1]))
    n = int(np.ceil(max(end - start, 0.0) * density / row.spacing_m[0])) + 1
    station = start + np.cumsum(rng.uniform(*row.spacing_m, n) / density)
    setback = rng.uniform(*row.setback_m, n)
    height = rng.uniform(*row.height_m, n)
    radius = rng.uniform(*row.crown_radius_m, n)
    trunk_r = height * rng.uniform(0.012, 0.018, n)
    crown_h = height * (1.0 - rng.uniform(*row.crown_base, n)) / 2
    keep = station < end
    station, setback, height, radius, trunk_r, crown_h = (a[keep] for a in (station, setback, height, radius, trunk_r, crown_h))
    xy, nl, wl, wr = line.sample(station)
    width = wl if row.side == "left" else wr
    xy = xy + line.side_sign(row.side) * nl * (width + setback)[:, None]
    on_land = edges.clearance(row.side, xy) >= 0.5
    z = ground_height(channel, row.side, station, setback)
    return np.c_[xy, z][on_land], height[on_land], radius[on_land], trunk_r[on_land], crown_h[on_land]


def _trunks(base: np.ndarray, top: np.ndarray, radius: np.ndarray) -> trimesh.Trimesh:
    """Closed hexagonal prisms from 1 m under the ground to the crown centre, one per tree."""
    unit = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=TRUNK_SECTIONS)
    v = np.asarray(unit.vertices)
    z0 = base[:, 2] - 1.0
    scale = np.stack([radius, radius, top - z0], 1)
    shift = np.c_[base[:, :2], 0.5 * (z0 + top)]
    vertices = v[None] * scale[:, None] + shift[:, None]
    faces = np.asarray(unit.faces)[None] + (len(v) * np.arange(len(base)))[:, None, None]
    return trimesh.Trimesh(vertices.reshape(-1, 3), faces.reshape(-1, 3), process=False)


def _facets(crowns: Crowns, foliage: Foliage, rng: np.random.Generator) -> trimesh.Trimesh:
    """Randomly placed and oriented equilateral facets filling each crown's spheroid at `leaf_density`
    (side `facet_m`, finer in small crowns);
    every vertex stays inside it (facet centres are drawn in the spheroid shrunk by the facet's
    circumradius, and counted by that inner volume)."""
    side = np.minimum(foliage.facet_m, SMALL_CROWN_FACET * crowns.radius.min(axis=1))
    circum = side / np.sqrt(3.0)
    inner = np.c_[crowns.radius[:, :1], crowns.radius] - circum[:, None]
    count = np.maximum(np.round(foliage.leaf_density * 4.0 / 3.0 * np.pi * inner.prod(axis=1) / (np.sqrt(3.0) / 4.0 * side**2)), 1)
    tree = np.repeat(np.arange(len(crowns)), count.astype(int))
    n = len(tree)
    direction = rng.standard_normal((n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    centre = crowns.centre[tree] + direction * inner[tree] * np.cbrt(rng.random(n))[:, None]
    q = rng.standard_normal((n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    angles = np.radians([90.0, 210.0, 330.0])
    template = np.c_[np.cos(angles), np.sin(angles), np.zeros(3)]  # unit circumradius, in the facet's plane
    vertices = centre[:, None, :] + circum[tree, None, None] * np.einsum("nij,vj->nvi", _rotation(q), template)
    return trimesh.Trimesh(vertices.reshape(-1, 3), np.arange(3 * n).reshape(-1, 3), process=False)


def _rotation(q: np.ndarray) -> np.ndarray:
    """(N, 3, 3) rotation matrices of unit quaternions (w, x, y, z) (N, 4); uniform ones give uniform rotations."""
    w, x, y, z = q.T
    return np.stack(
        [
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        1,
    )
