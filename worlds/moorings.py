"""Docks, floating pontoons, piles and moored boats beside the channel.

A `Dock` is a fixed pier on timber piles (deck 1.2 m above the water) or a floating pontoon (0.5 m
freeboard, steel guide piles), reaching out from the channel edge ('across') or lying along it
('along'), with boats moored alongside. A `MooringField` is a grid of boats on swing moorings
(or, with one row and no jitter, a line of boats along a quay). A dock that would come too close
to the route or run into a structure (a narrow canal, a moved bridge) is left out, and so is a boat
that would not float clear of the route, the edge, the structures and the docks. Every draw comes from
`riverbench.rng.stream(seed, "worlds.moorings")`.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field, model_validator

from riverbench.rng import stream
from worlds.boats import Boats, build_boats, draw
from worlds.channel import Centerline
from worlds.geometry import box, merge, pipe
from worlds.materials import STEEL, TIMBER
from worlds.placement import SOLID_KINDS, Edges, RouteDistance, SolidDistance
from worlds.world import Part

PIER_DECK_M = (0.9, 1.2)
"""Fixed pier deck underside and top above the water, m."""
PONTOON_M = (-0.4, 0.5)
"""Floating pontoon bottom and deck above the water, m."""
BERTH_GAP_M = 0.3
DOCK_KINDS = ("dock", "pontoon", "pile")


class BoatMix(BaseModel):
    """Which boats: length range and share of sailboats."""

    model_config = ConfigDict(extra="forbid")

    boat_length_m: tuple[float, float] = Field((5.0, 9.0), description="range of hull lengths, m")
    sail_share: float = Field(0.5, ge=0.0, le=1.0, description="share of sailboats (the rest are motor boats)")

    @model_validator(mode="after")
    def _range(self) -> BoatMix:
        lo, hi = self.boat_length_m
        if not 2.0 <= lo <= hi <= 30.0:
            raise ValueError(f"boat_length_m: need 2 <= min <= max <= 30, got ({lo}, {hi})")
        return self


class Dock(BoatMix):
    """A fixed pier or floating pontoon at the channel edge, with boats alongside."""

    name: str = Field(..., min_length=1, description="unique name (in world.params['docks'])")
    side: Literal["left", "right"] = Field(..., description="side of the route, looking along it")
    station_m: float = Field(..., description="route station of the dock's root (across) or middle (along), m")
    type: Literal["pier", "pontoon"] = Field("pontoon", description="pier: fixed deck on timber piles; pontoon: floating, with guide piles")
    orientation: Literal["across", "along"] = Field("across", description="across: reaches out from the edge; along: lies against it")
    length_m: float = Field(30.0, gt=2.0, le=300.0, description="deck length, m")
    width_m: float = Field(2.5, gt=0.5, le=20.0, description="deck width, m")
    boats: int = Field(0, ge=0, le=200, description="boats moored alongside (both sides across, the water side along; capped by its length)")


class MooringField(BoatMix):
    """Boats on moorings in a grid off one bank between two stations, bows upstream into the current."""

    name: str = Field(..., min_length=1, description="unique name (in world.params['mooring_fields'])")
    side: Literal["left", "right"] = Field(..., description="side of the route, looking along it")
    start_m: float = Field(..., description="route station where the field starts, m")
    end_m: float = Field(..., description="route station where the field ends, m")
    offset_m: tuple[float, float] = Field((10.0, 40.0), description="range of distances from the channel edge to the boats' near sides, m")
    spacing_m: float = Field(18.0, ge=10.0, le=200.0, description="grid spacing between moorings (along and across), m")
    jitter_deg: float = Field(20.0, ge=0.0, le=90.0, description="spread of the boats' headings about upstream, deg (0: a tidy line along a quay)")


def build_moorings(
    docks: list[Dock],
    fields: list[MooringField],
    line: Centerline,
    edges: Edges,
    parts: list[Part],
    seed: int,
    density: float,
    route_distance: RouteDistance,
    clearance_m: float,
    with_docks: bool,
    with_boats: bool,
) -> tuple[list[Part], list[Dock]]:
    """Dock, pontoon and pile parts (when `with_docks`) and moored-boat parts (when `with_boats`;
    `density` scales the boats per dock and per field), and the docks placed."""
    rng = stream(seed, "worlds.moorings")
    solids = SolidDistance(parts)
    out: list[Part] = []
    boats, placed = [], []
    if with_docks:
        meshes: dict[tuple[str, str], list[trimesh.Trimesh]] = {}
        for dock in docks:
            mine, berths = _dock(dock, line, rng, density)
            deck = np.asarray(mine[(dock.type if dock.type == "pontoon" else "dock", "timber")][0].vertices)
            if route_distance(deck).min() < clearance_m or solids(deck).min() < 0.3:
                continue
            placed.append(dock)
            for key, m in mine.items():
                meshes.setdefault(key, []).extend(m)
            boats.append(berths)
        for (kind, material), m in meshes.items():
            out.append(Part(f"{kind}s_{material}", kind, {"timber": TIMBER, "steel": STEEL}[material], merge(m)))
    if not with_boats:
        return out, placed
    docked = _afloat(Boats.concatenate(boats), edges, route_distance, clearance_m, solids)
    crowded = SolidDistance(parts + out + build_boats(docked), SOLID_KINDS + DOCK_KINDS + ("moored_boat",))
    moored = _afloat(Boats.concatenate([_field(f, line, rng, density) for f in fields]), edges, route_distance, clearance_m, crowded)
    return out + build_boats(Boats.concatenate([docked, moored])), placed


def _frame(line: Centerline, side: str, station: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Edge point at `station` on `side`, unit vector from it into the water, unit tangent along the route."""
    xy, nl, wl, wr = line.sample(np.array([station]))
    out = line.side_sign(side) * nl[0]
    width = (wl if side == "left" else wr)[0]
    return xy[0] + out * width, -out, np.array([nl[0, 1], -nl[0, 0]])


def _dock(dock: Dock, line: Centerline, rng: np.random.Generator, density: float):
    """Meshes of one dock by (kind, material), and the boats alongside it."""
    root, water, tangent = _frame(line, dock.side, dock.station_m)
    if dock.orientation == "across":
        axis, centre = water, root + water * dock.length_m / 2
    else:
        axis, centre = tangent, root + water * (dock.width_m / 2 + 0.05)
    perp = np.array([-axis[1], axis[0]])
    sides = (1.0, -1.0) if dock.orientation == "across" else (float(np.sign(perp @ water)),)  # along: the water side only
    lo, hi = PIER_DECK_M if dock.type == "pier" else PONTOON_M
    deck = box(np.r_[centre, 0.5 * (lo + hi)], axis, (dock.length_m, dock.width_m, hi - lo))
    if dock.type == "pier":
        t = np.arange(-dock.length_m / 2 + 0.3, dock.length_m / 2, 4.0)
        piles = [
            pipe(np.r_[p, -2.0], np.r_[p, hi + 0.5], 0.15) for s in (1.0, -1.0) for p in centre + np.outer(t, axis) + s * perp * dock.width_m / 2
        ]
        meshes = {("dock", "timber"): [deck], ("pile", "timber"): piles}
    else:
        t = np.arange(-dock.length_m / 2 + 1.0, dock.length_m / 2, 12.0)
        piles = [
            pipe(np.r_[p, -2.0], np.r_[p, 3.0], 0.2, sections=8)
            for s in sides
            for p in centre + np.outer(t, axis) + s * perp * (dock.width_m / 2 + 0.25)
        ]
        meshes = {("pontoon", "timber"): [deck], ("pile", "steel"): piles}
    n = int(round(dock.boats * density))
    size = draw(rng, n, dock.boat_length_m, dock.sail_share)
    slot = dock.boat_length_m[1] + 1.0
    k = np.arange(n) // len(sides)
    start = -dock.length_m / 2 + (2.0 if dock.orientation == "across" else 0.0)
    along = start + (k + 0.5) * slot
    side = np.asarray(sides)[np.arange(n) % len(sides)]
    across = side * (dock.width_m / 2 + 0.45 + BERTH_GAP_M + size["beam"] / 2)  # guide piles stand 0.45 m out
    xy = centre + along[:, None] * axis + across[:, None] * perp
    fits = along + slot / 2 <= dock.length_m / 2
    boats = Boats(xy=xy, heading=np.full(n, np.arctan2(axis[1], axis[0])), **size).take(fits)
    return meshes, boats


def _field(field: MooringField, line: Centerline, rng: np.random.Generator, density: float) -> Boats:
    """Candidate boats of a mooring field: grid over stations and offsets, bows upstream, sizes drawn."""
    step = field.spacing_m / np.sqrt(density)
    stations = np.arange(field.start_m + step / 2, field.end_m, step)
    offsets = np.arange(field.offset_m[0], field.offset_m[1] + 1e-9, step)
    s, off = (a.ravel() for a in np.meshgrid(stations, offsets, indexing="ij"))
    n = len(s)
    size = draw(rng, n, field.boat_length_m, field.sail_share)
    s = s + rng.uniform(-1.0, 1.0, n) * (field.jitter_deg > 0)
    heading = np.interp(s, line.s, line.heading) + np.pi + np.radians(field.jitter_deg) * rng.uniform(-1.0, 1.0, n)
    xy, nl, wl, wr = line.sample(s)
    sign = line.side_sign(field.side)
    width = wl if field.side == "left" else wr
    xy = xy + sign * nl * (width - off - size["beam"] / 2)[:, None]
    return Boats(xy=xy, heading=heading, **size)


def _afloat(boats: Boats, edges: Edges, route_distance: RouteDistance, clearance_m: float, solids: SolidDistance) -> Boats:
    """The boats whose footprint is on the water on both sides' terms, `clearance_m` from the route
    and clear of `solids` by half its length."""
    if not len(boats):
        return boats
    corners = boats.corners().reshape(-1, 2)
    ok = route_distance(corners).reshape(-1, 4).min(axis=1) >= clearance_m
    for side in ("left", "right"):
        ok &= edges.clearance(side, corners).reshape(-1, 4).max(axis=1) <= -BERTH_GAP_M
    ok &= solids(np.c_[boats.xy, np.full(len(boats), 0.5)]) > boats.length / 2
    return boats.take(ok)
