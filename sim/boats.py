"""Other vessels' bodies: a motor-boat hull (stern square, bow tapering to a stem) with a cabin, in a few sizes.

Meshes are in the boat's body frame like base_link: x forward, y left, z up from the waterline,
the hull centred on the origin. Each is closed (watertight), so the GNSS model reflects only off
its outer side, and built of trimesh primitives (a convex hull and boxes).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field

from worlds.materials import STEEL, Material

GELCOAT = Material("gelcoat", reflectivity=0.6, gnss_reflective=False)
"""White fibreglass hull: bright at 905 nm; thin GRP lets L1 through rather than reflecting it."""

BoatKind = Literal["runabout", "cruiser", "barge"]


class BoatShape(BaseModel):
    """Dimensions of a hull with one cabin (or console, or wheelhouse), metres."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    length_m: float = Field(..., gt=0, description="overall length")
    beam_m: float = Field(..., gt=0, description="widest width")
    freeboard_m: float = Field(..., gt=0, description="deck edge above the waterline")
    draft_m: float = Field(..., gt=0, description="keel below the waterline")
    bow_fraction: float = Field(..., gt=0, lt=1, description="share of the length over which the bow tapers to the stem")
    cabin_length_m: float = Field(..., gt=0, description="cabin length")
    cabin_width_m: float = Field(..., gt=0, description="cabin width")
    cabin_height_m: float = Field(..., gt=0, description="cabin top above the deck")
    cabin_x_m: float = Field(..., description="cabin centre forward of midships")


BOATS: dict[str, tuple[BoatShape, Material]] = {
    # a 5.5 m centre-console runabout, the kind a field team drives a chase boat in
    "runabout": (
        BoatShape(
            length_m=5.5,
            beam_m=2.2,
            freeboard_m=0.8,
            draft_m=0.4,
            bow_fraction=0.35,
            cabin_length_m=1.0,
            cabin_width_m=1.0,
            cabin_height_m=1.1,
            cabin_x_m=0.2,
        ),
        GELCOAT,
    ),
    # a 10 m cabin cruiser
    "cruiser": (
        BoatShape(
            length_m=10.0,
            beam_m=3.4,
            freeboard_m=1.2,
            draft_m=0.8,
            bow_fraction=0.3,
            cabin_length_m=4.5,
            cabin_width_m=2.8,
            cabin_height_m=1.7,
            cabin_x_m=-0.5,
        ),
        GELCOAT,
    ),
    # a 30 m steel work barge with a wheelhouse aft, its top 7.5 m above the water
    "barge": (
        BoatShape(
            length_m=30.0,
            beam_m=9.0,
            freeboard_m=1.5,
            draft_m=1.5,
            bow_fraction=0.08,
            cabin_length_m=4.0,
            cabin_width_m=6.0,
            cabin_height_m=6.0,
            cabin_x_m=-12.0,
        ),
        STEEL,
    ),
}
"""Boat kinds by name: shape and hull material."""


def boat_mesh(shape: BoatShape) -> trimesh.Trimesh:
    """Hull (convex: square stern, straight sides, bow tapering to a stem on the centreline) plus the cabin box."""
    half_l, half_b = shape.length_m / 2, shape.beam_m / 2
    shoulder = half_l - shape.bow_fraction * shape.length_m
    plan = np.array([[-half_l, -half_b], [shoulder, -half_b], [half_l, 0.0], [shoulder, half_b], [-half_l, half_b]])
    keel = plan * [1.0, 0.8]  # the bottom is a little narrower: a sloped hull side
    keel[2, 0] = shoulder + 0.3 * (half_l - shoulder)  # raked stem
    points = np.vstack([np.c_[plan, np.full(5, shape.freeboard_m)], np.c_[keel, np.full(5, -shape.draft_m)]])
    hull = trimesh.convex.convex_hull(points)
    cabin = trimesh.creation.box(extents=(shape.cabin_length_m, shape.cabin_width_m, shape.cabin_height_m))
    cabin.apply_translation((shape.cabin_x_m, 0.0, shape.freeboard_m + shape.cabin_height_m / 2))
    mesh = trimesh.util.concatenate([hull, cabin])
    assert isinstance(mesh, trimesh.Trimesh)  # concatenating meshes gives a mesh
    return mesh


def boat(kind: str) -> tuple[trimesh.Trimesh, Material]:
    """The mesh and material of a boat kind in BOATS."""
    if kind not in BOATS:
        raise ValueError(f"boat: unknown kind {kind!r} (one of {', '.join(BOATS)})")
    shape, material = BOATS[kind]
    return boat_mesh(shape), material
