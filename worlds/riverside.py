"""The living riverside: trees, docks and moored boats a preset places, and the switches that thin them.

A preset describes where its tree rows, docks and mooring fields are (`Riverside`); its parameter
model inherits `RiversideParams`, which turns each kind off or scales its density. Nothing comes
closer than `route_clearance_m` to the route the vessel follows.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from pydantic import BaseModel, ConfigDict, Field

from worlds.channel import Centerline, ChannelParams
from worlds.crowns import Crowns
from worlds.moorings import Dock, MooringField, build_moorings
from worlds.placement import Edges, RouteDistance, SolidDistance
from worlds.route import Route
from worlds.vegetation import Foliage, TreeRow, build_trees
from worlds.world import Part


class RiversideParams(BaseModel):
    """Switches and densities of what lives along the banks."""

    model_config = ConfigDict(extra="forbid")

    vegetation: bool = Field(True, description="place the preset's trees (trunks and porous crowns)")
    tree_density: float = Field(1.0, gt=0.0, le=3.0, description="multiplies the number of trees per row (divides their spacing)")
    foliage: Foliage = Field(default_factory=Foliage, description="how crowns are filled with facets")
    docks: bool = Field(True, description="place the preset's docks, pontoons and their piles")
    moored_boats: bool = Field(True, description="place boats at the docks and in the mooring fields")
    mooring_density: float = Field(1.0, gt=0.0, le=3.0, description="multiplies the boats per dock and per mooring field")
    route_clearance_m: float = Field(
        8.0, ge=2.0, le=100.0, description="nothing placed comes closer to the route, m (a 2.4 m hull plus lateral offsets)"
    )


@dataclass(frozen=True)
class Riverside:
    """Where a preset's trees, docks and mooring fields are, and its switches."""

    params: RiversideParams
    trees: list[TreeRow] = field(default_factory=list)
    docks: list[Dock] = field(default_factory=list)
    fields: list[MooringField] = field(default_factory=list)


def build_riverside(
    riverside: Riverside, route: Route, line: Centerline, channel: ChannelParams, parts: list[Part], seed: int
) -> tuple[list[Part], Crowns, dict]:
    """Parts, crown envelopes and a json-able summary of the riverside, placed around the `parts` built so far."""
    p = riverside.params
    names = [d.name for d in riverside.docks] + [f.name for f in riverside.fields]
    if len(set(names)) != len(names):
        raise ValueError(f"dock and mooring field names must be unique, got {names}")
    near_route, edges = RouteDistance(route), Edges(line)
    out: list[Part] = []
    crowns = Crowns.empty()
    if p.vegetation and riverside.trees:
        trees, crowns = build_trees(
            riverside.trees, line, edges, channel, seed, p.tree_density, p.foliage, near_route, SolidDistance(parts), p.route_clearance_m
        )
        out += trees
    moorings, docks = build_moorings(
        riverside.docks, riverside.fields, line, edges, parts, seed, p.mooring_density, near_route, p.route_clearance_m, p.docks, p.moored_boats
    )
    out += moorings
    summary = {
        "trees": len(crowns),
        "docks": [d.model_dump(mode="json", include={"name", "side", "station_m", "type", "orientation", "length_m"}) for d in docks],
        "mooring_fields": [f.model_dump(mode="json", include={"name", "side", "start_m", "end_m"}) for f in riverside.fields]
        if p.moored_boats
        else [],
    }
    return out, crowns, summary
