"""The World: named, typed mesh parts, the route the vessel follows, and a geodetic origin."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, cast

import numpy as np
import trimesh

from worlds.crowns import Crowns
from worlds.materials import Material
from worlds.route import Route

if TYPE_CHECKING:
    import open3d as o3d

PART_KINDS = (
    "water",
    "wall",
    "quay",
    "bank",
    "bridge_deck",
    "pier",
    "girder",
    "arch",
    "lock_wall",
    "lock_gate",
    "building",
    "tree",
    "foliage",
    "dock",
    "pontoon",
    "pile",
    "moored_boat",
    "other",
)
"""tree: trunks (solid: they block GNSS like any solid); foliage: porous crowns (GNSS crosses them
attenuated, see `World.crowns`); dock: fixed piers on piles; pontoon: floating docks; pile: piles
and mooring posts; moored_boat: hulls, cabins and masts of boats at docks and moorings."""


@dataclass
class Part:
    """One named piece of the world: a triangle mesh of one kind and one material."""

    name: str
    kind: str
    material: Material
    mesh: trimesh.Trimesh

    def __post_init__(self) -> None:
        if self.kind not in PART_KINDS:
            raise ValueError(f"part {self.name!r}: unknown kind {self.kind!r} (one of {', '.join(PART_KINDS)})")
        vertices = np.asarray(self.mesh.vertices)
        if len(self.mesh.faces) == 0:
            raise ValueError(f"part {self.name!r}: mesh has no triangles")
        if not np.isfinite(vertices).all():
            raise ValueError(f"part {self.name!r}: mesh has NaN or infinite vertices")


@dataclass
class World:
    """A meshed river world in ENU metres about `origin` = (lat_deg, lon_deg, alt_m).

    `crowns` are the envelopes of the foliage parts' crowns, for GNSS attenuation (empty if none).
    """

    name: str
    parts: list[Part]
    route: Route
    origin: tuple[float, float, float]
    params: dict = field(default_factory=dict)
    crowns: Crowns = field(default_factory=Crowns.empty)

    def __post_init__(self) -> None:
        if not self.parts:
            raise ValueError(f"world {self.name!r}: has no parts")
        names = [p.name for p in self.parts]
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise ValueError(f"world {self.name!r}: duplicate part names {dup}")

    @cached_property
    def mesh(self) -> trimesh.Trimesh:
        """Every part in one mesh; faces keep the order of `parts` (see `face_part`)."""
        return cast(trimesh.Trimesh, trimesh.util.concatenate([p.mesh for p in self.parts]))  # meshes in, a mesh out

    @cached_property
    def face_part(self) -> np.ndarray:
        """Index into `parts` of every face of `mesh` (uint16), to label what a ray hit."""
        counts = [len(p.mesh.faces) for p in self.parts]
        return np.repeat(np.arange(len(self.parts), dtype=np.uint16), counts)

    @cached_property
    def part_reflectivity(self) -> np.ndarray:
        """905 nm reflectivity per part index (float32)."""
        return np.array([p.material.reflectivity for p in self.parts], dtype=np.float32)

    @cached_property
    def face_reflectivity(self) -> np.ndarray:
        """905 nm reflectivity of every face of `mesh` (float32): the per-triangle material lookup of a ray hit."""
        return self.part_reflectivity[self.face_part]

    @cached_property
    def face_is_water(self) -> np.ndarray:
        """True for every face of `mesh` on a water surface."""
        return self.part_is_water[self.face_part]

    @cached_property
    def face_is_foliage(self) -> np.ndarray:
        """True for every face of `mesh` on a porous tree crown (worlds.vegetation's facets)."""
        return np.array([p.material.foliage for p in self.parts], dtype=bool)[self.face_part]

    @cached_property
    def part_is_water(self) -> np.ndarray:
        """True per part index for water surfaces."""
        return np.array([p.material.water for p in self.parts], dtype=bool)

    @cached_property
    def raycasting_scene(self) -> o3d.t.geometry.RaycastingScene:
        """Open3D (Embree) scene of `mesh`, built once per world; geometry id 0."""
        return _scene(self.mesh)

    @cached_property
    def gnss_scene(self) -> o3d.t.geometry.RaycastingScene:
        """Scene of what blocks GNSS signals: every part but foliage (the same scene when there is none)."""
        solid = [p.mesh for p in self.parts if not p.material.foliage]
        return self.raycasting_scene if len(solid) == len(self.parts) else _scene(cast(trimesh.Trimesh, trimesh.util.concatenate(solid)))

    def part(self, name: str) -> Part:
        """The part called `name`."""
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(f"world {self.name!r} has no part {name!r}")

    def parts_of_kind(self, *kinds: str) -> list[Part]:
        """All parts whose kind is one of `kinds`."""
        return [p for p in self.parts if p.kind in kinds]


def _scene(mesh: trimesh.Trimesh) -> o3d.t.geometry.RaycastingScene:
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(
        o3d.core.Tensor(np.asarray(mesh.vertices, dtype=np.float32)),
        o3d.core.Tensor(np.asarray(mesh.faces, dtype=np.uint32)),
    )
    return scene
