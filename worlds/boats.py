"""Moored boats: motor boats (hull and cabin) and sailboats (hull, mast and boom) from unit templates.

Each boat is a transformed copy of a few closed template meshes, so any number of boats is built
with a handful of vectorised operations. Hulls are pointed-bow prisms from 0.4 m under the water
to their freeboard; a sailboat's mast is ~1.3 hull lengths tall, as on dinghies and small keelboats.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import trimesh

from worlds.geometry import merge
from worlds.materials import ALUMINIUM, FIBREGLASS
from worlds.world import Part

DRAFT_M = 0.4
_OUTLINE = np.array([[-0.5, -0.5], [0.15, -0.5], [0.5, 0.0], [0.15, 0.5], [-0.5, 0.5]])  # unit deck plan, bow at +x
_HULL = trimesh.convex.convex_hull(np.r_[np.c_[_OUTLINE * [0.95, 0.7], np.zeros(5)], np.c_[_OUTLINE, np.ones(5)]])  # flared
_BOX = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
_ROD = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=6)  # along z, centred


@dataclass(frozen=True)
class Boats:
    """N boats: centre xy (N, 2), heading (N,) rad, length, beam, freeboard (N,) m, sail (N,) bool,
    rig (N,) m: cabin height above the deck of a motor boat, mast height of a sailboat."""

    xy: np.ndarray
    heading: np.ndarray
    length: np.ndarray
    beam: np.ndarray
    freeboard: np.ndarray
    sail: np.ndarray
    rig: np.ndarray

    def __len__(self) -> int:
        return len(self.xy)

    def take(self, keep: np.ndarray) -> Boats:
        return Boats(*(getattr(self, f)[keep] for f in FIELDS))

    @classmethod
    def concatenate(cls, boats: list[Boats]) -> Boats:
        empty = (np.zeros((0, 2)), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0), np.zeros(0, bool), np.zeros(0))
        return cls(*(np.concatenate([getattr(b, f) for b in boats] + [e]) for f, e in zip(FIELDS, empty)))

    def corners(self) -> np.ndarray:
        """(N, 4, 2) corners of each boat's rectangular footprint."""
        u = np.stack([np.cos(self.heading), np.sin(self.heading)], 1)
        v = np.stack([-u[:, 1], u[:, 0]], 1)
        sx = np.array([-0.5, 0.5, 0.5, -0.5])[None, :, None] * self.length[:, None, None]
        sy = np.array([-0.5, -0.5, 0.5, 0.5])[None, :, None] * self.beam[:, None, None]
        return self.xy[:, None, :] + sx * u[:, None, :] + sy * v[:, None, :]


FIELDS = ("xy", "heading", "length", "beam", "freeboard", "sail", "rig")


def draw(rng: np.random.Generator, n: int, length_m: tuple[float, float], sail_share: float) -> dict[str, np.ndarray]:
    """Sizes of n boats: length in range, beam ~1/3 of it, freeboard, which are sailboats, and their rig."""
    length = rng.uniform(*length_m, n)
    sail = rng.random(n) < sail_share
    beam = length * np.where(sail, rng.uniform(0.30, 0.35, n), rng.uniform(0.33, 0.38, n))
    freeboard = np.where(sail, rng.uniform(0.5, 0.9, n), rng.uniform(0.8, 1.2, n))
    rig = np.where(sail, length * rng.uniform(1.2, 1.4, n), rng.uniform(1.0, 1.6, n))
    return {"length": length, "beam": beam, "freeboard": freeboard, "sail": sail, "rig": rig}


def build_boats(boats: Boats) -> list[Part]:
    """Hull-and-cabin part (fibreglass) and mast-and-boom part (aluminium), both of kind moored_boat."""
    if not len(boats):
        return []
    n = len(boats)
    L, B, F = boats.length, boats.beam, boats.freeboard
    zeros = np.zeros(n)
    hulls = _instances(_HULL, boats, np.stack([L, B, F + DRAFT_M], 1), np.stack([zeros, zeros, np.full(n, -DRAFT_M)], 1))
    motor = ~boats.sail
    cabin_h = boats.rig
    cabins = _instances(
        _BOX, boats.take(motor), np.stack([0.4 * L, 0.7 * B, cabin_h], 1)[motor], np.stack([-0.05 * L, zeros, F + cabin_h / 2], 1)[motor]
    )
    sail = boats.take(boats.sail)
    ls, fs = sail.length, sail.freeboard
    mast_h = sail.rig
    z = np.zeros(len(sail))
    masts = _instances(
        _ROD, sail, np.stack([np.full(len(sail), 0.06), np.full(len(sail), 0.06), mast_h], 1), np.stack([0.1 * ls, z, fs + mast_h / 2], 1)
    )
    booms = _instances(
        _ROD,
        sail,
        np.stack([0.45 * ls, np.full(len(sail), 0.05), np.full(len(sail), 0.05)], 1),
        np.stack([-0.125 * ls, z, fs + 1.0], 1),
        lie_along_x=True,
    )
    parts = [Part("moored_boat_hulls", "moored_boat", FIBREGLASS, merge([m for m in (hulls, cabins) if m is not None]))]
    if masts is not None and booms is not None:  # None exactly when no boat has a sail
        parts.append(Part("moored_boat_masts", "moored_boat", ALUMINIUM, merge([masts, booms])))
    return parts


def _instances(template: trimesh.Trimesh, boats: Boats, scale: np.ndarray, shift: np.ndarray, lie_along_x: bool = False) -> trimesh.Trimesh | None:
    """One copy of `template` per boat: scaled, shifted in the boat frame (x bow, z up), placed."""
    if not len(boats):
        return None
    v = np.asarray(template.vertices)
    if lie_along_x:
        v = v[:, [2, 1, 0]]
    local = v[None] * scale[:, None] + shift[:, None]
    c, s = np.cos(boats.heading)[:, None], np.sin(boats.heading)[:, None]
    world = np.stack(
        [boats.xy[:, :1] + c * local[..., 0] - s * local[..., 1], boats.xy[:, 1:] + s * local[..., 0] + c * local[..., 1], local[..., 2]], -1
    )
    faces = np.asarray(template.faces)
    if lie_along_x:
        faces = faces[:, ::-1]  # swapping two axes mirrors the mesh: keep the normals outward
    faces = faces[None] + (len(v) * np.arange(len(boats)))[:, None, None]
    return trimesh.Trimesh(world.reshape(-1, 3), faces.reshape(-1, 3), process=False)
