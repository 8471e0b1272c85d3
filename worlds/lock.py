"""A navigation lock on the route: chamber walls narrowing the channel, open gates, a road on top.

The chamber is centred on the route at `station_m` and its walls follow the route at
+-chamber_width_m/2, so the vessel passes through its middle. Each wall is a solid block from the
chamber face out past the channel edge (the dam), from `below_m` under the water to `top_m` above.
Gates stand open: mitre gate leaves folded into recesses in the chamber walls, or lift gates
raised to `lift_clearance_m`. A road crosses on top at the downstream end.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field

from worlds.channel import Centerline
from worlds.geometry import box, merge, mesh_from, orient, strip
from worlds.materials import MATERIALS
from worlds.route import Route
from worlds.world import Part


class LockSpec(BaseModel):
    """One navigation lock; lengths in metres."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field("lock", min_length=1, description="unique name, used in part names and world.params['structures']")
    station_m: float = Field(..., description="route station of the chamber centre, m")
    length_m: float = Field(70.0, gt=10.0, le=500.0, description="chamber length along the route, m")
    chamber_width_m: float = Field(14.0, gt=4.0, le=60.0, description="clear width between the chamber walls, m")
    top_m: float = Field(4.0, gt=0.5, le=20.0, description="chamber wall top above the water, m")
    below_m: float = Field(4.0, gt=0.5, le=30.0, description="depth of the chamber walls below the water, m")
    gate_type: Literal["mitre", "lift"] = Field("mitre", description="mitre: leaves open in wall recesses; lift: gates raised above the water")
    gate_thickness_m: float = Field(0.6, gt=0.05, le=5.0, description="thickness of a gate leaf or lift gate, m")
    lift_clearance_m: float = Field(9.0, gt=1.0, le=40.0, description="lift gates: height of the raised gate's bottom above the water, m")
    road_width_m: float = Field(14.0, ge=0.0, le=80.0, description="width of the road crossing on top at the downstream end (0 = none), m")
    road_height_m: float = Field(6.0, gt=0.5, le=40.0, description="height of the road deck's underside above the water, m")

    def stations(self) -> tuple[float, float]:
        """Upstream and downstream ends of the chamber."""
        return self.station_m - self.length_m / 2, self.station_m + self.length_m / 2

    def gate_stations(self) -> tuple[float, float]:
        """Stations of the upstream and downstream gates (the road sits downstream of the second)."""
        a, b = self.stations()
        return a + 4.0, b - self.road_width_m - 4.0

    def leaf_m(self) -> float:
        """Length of one mitre leaf (half the chamber at a 20 deg mitre)."""
        return self.chamber_width_m / 2 / np.cos(np.radians(20.0))

    def check(self, route: Route) -> None:
        """Raise ValueError when the lock does not fit on the route or its parts overlap."""
        a, b = self.stations()
        if a <= 0 or b >= route.length:
            raise ValueError(
                f"lock {self.name!r}: station_m={self.station_m} with length_m={self.length_m} is outside the route (0, {route.length:.1f})"
            )
        g0, g1 = self.gate_stations()
        if self.gate_type == "mitre" and g0 + self.leaf_m() >= g1 - self.leaf_m():
            raise ValueError(f"lock {self.name!r}: length_m={self.length_m} too short for its mitre gates and road")
        i = (route.s >= a) & (route.s <= b)
        narrow = min(route.left_m[i].min(), route.right_m[i].min())
        if self.chamber_width_m / 2 + 1.0 >= narrow:
            raise ValueError(f"lock {self.name!r}: chamber_width_m={self.chamber_width_m} does not fit the channel ({2 * narrow:.1f} m)")


def _block(
    line: Centerline, side: str, s0: float, s1: float, off_in: float, off_out: np.ndarray | float, z0: float, z1: float, n: int, bottom: bool = False
) -> trimesh.Trimesh:
    """Solid following the route between stations s0..s1, `off_in`..`off_out` to one side, z0..z1.

    Inner face, top, outer face and both end caps, normals pointing out of the solid; the bottom
    only when asked (under the water it is never seen).
    """
    s = np.linspace(s0, s1, n)
    xy, nl, _, _ = line.sample(s)
    sign = line.side_sign(side)
    off_out = np.broadcast_to(np.asarray(off_out, float), s.shape)
    inner = xy + sign * nl * off_in
    outer = xy + sign * nl * off_out[:, None]

    def at(p: np.ndarray, z: float) -> np.ndarray:
        return np.c_[p, np.full(len(p), z)]

    ring = [at(inner, z0), at(inner, z1), at(outer, z1), at(outer, z0)] + ([at(inner, z0)] if bottom else [])
    sides = strip(np.stack(ring))
    mid = np.c_[0.5 * (inner + outer), np.full(n, 0.5 * (z0 + z1))]
    centroid = np.asarray(sides.triangles_center)
    nearest = np.argmin(np.linalg.norm(centroid[:, None, :] - mid[None, :, :], axis=2), axis=1)
    faces = [orient(sides, centroid - mid[nearest])]
    tangent = np.r_[xy[-1] - xy[0], 0.0]
    for k, toward in ((0, -tangent), (-1, tangent)):
        quad = np.array([[*inner[k], z0], [*inner[k], z1], [*outer[k], z1], [*outer[k], z0]])
        faces.append(orient(mesh_from(quad, np.array([[0, 1, 2], [0, 2, 3]])), toward))
    return merge(faces)


def build_lock(spec: LockSpec, route: Route) -> list[Part]:
    """Chamber walls (with recesses for open mitre leaves), gates and the road deck."""
    spec.check(route)
    line = Centerline.of(route, 0.0)
    a, b = spec.stations()
    half = spec.chamber_width_m / 2
    g0, g1 = spec.gate_stations()
    recess = spec.gate_thickness_m + 0.3
    leaf = spec.leaf_m()
    recesses = [(g0, g0 + leaf + 0.5), (g1 - leaf - 0.5, g1)] if spec.gate_type == "mitre" else []
    cuts = [a, *[c for r in recesses for c in r], b]
    walls, gates = [], []
    for side in ("left", "right"):
        width = line.left if side == "left" else line.right
        for s0, s1 in zip(cuts[:-1], cuts[1:]):
            in_recess = any(abs(s0 - r0) < 1e-9 for r0, _ in recesses)
            # full-depth segments reach 5 cm into the recesses: no zero-width crack at the steps
            w0, w1 = (s0, s1) if in_recess else (max(s0 - 0.05, a), min(s1 + 0.05, b))
            n = max(int((w1 - w0) / 2.0), 1) + 1
            outer = np.interp(np.linspace(w0, w1, n), line.s, width) + 3.0
            walls.append(_block(line, side, w0, w1, half + (recess if in_recess else 0.0), outer, -spec.below_m, spec.top_m, n))
            if in_recess:
                gates.append(
                    _block(line, side, s0 + 0.2, s1 - 0.5, half + 0.15, half + 0.15 + spec.gate_thickness_m, -spec.below_m + 0.5, spec.top_m - 0.3, n)
                )
    if spec.gate_type == "lift":
        for g in (g0, g1):
            xy, heading = route.at(g)
            nl = np.array([-np.sin(heading), np.cos(heading)])
            height = spec.top_m + spec.below_m
            gates.append(box(np.r_[xy, spec.lift_clearance_m + height / 2], nl, (spec.chamber_width_m + 1.0, spec.gate_thickness_m, height)))
            for sign in (-1, 1):
                tower_top = spec.lift_clearance_m + height + 1.5
                walls.append(box(np.r_[xy + sign * nl * (half + 1.5), 0.5 * (spec.top_m + tower_top)], nl, (3.0, 3.0, tower_top - spec.top_m)))
    parts = [
        Part(f"{spec.name}_walls", "lock_wall", MATERIALS["concrete"], merge(walls)),
        Part(f"{spec.name}_gates", "lock_gate", MATERIALS["steel"], merge(gates)),
    ]
    if spec.road_width_m > 0:
        parts.append(Part(f"{spec.name}_road", "bridge_deck", MATERIALS["concrete"], _road(spec, line)))
    return parts


def _road(spec: LockSpec, line: Centerline) -> trimesh.Trimesh:
    """Road deck over the downstream end, spanning the channel, on the walls (filled up to it)."""
    _, b = spec.stations()
    s0, s1 = b - spec.road_width_m, b
    blocks = []
    for side in ("left", "right"):
        width = line.left if side == "left" else line.right
        outer = float(np.interp(0.5 * (s0 + s1), line.s, width)) + 3.0
        blocks.append(_block(line, side, s0, s1, 0.0, outer, spec.road_height_m, spec.road_height_m + 1.0, 6, bottom=True))
        blocks.append(_block(line, side, s0, s1, spec.chamber_width_m / 2, outer, spec.top_m, spec.road_height_m, 6))
    return merge(blocks)


def summary(spec: LockSpec) -> dict:
    """Json-able record of the lock for world.params['structures']."""
    a, b = spec.stations()
    return {
        "name": spec.name,
        "type": "lock",
        "station_m": spec.station_m,
        "start_m": a,
        "end_m": b,
        "chamber_width_m": spec.chamber_width_m,
        "gate_type": spec.gate_type,
        "deck_height_m": spec.road_height_m,
        "deck_width_m": spec.road_width_m,
        "shadow_start_m": b - spec.road_width_m,
        "shadow_end_m": b,
    }
