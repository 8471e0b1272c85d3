"""City blocks: rows of upright box buildings set back behind the channel edge, drawn from a seed.

A row walks along the route on one side between two stations, placing buildings of random
frontage, depth, height and facade material with random gaps. Every draw comes from
`riverbench.rng.stream(seed, "worlds.buildings")`, so the same rows and seed give the same mesh.
Buildings that would reach closer than half the setback to the channel edge (inner side of a bend) or
that overlap a kept-clear station range (bridges, the lock) are skipped.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from riverbench.rng import stream
from worlds.channel import Centerline
from worlds.geometry import box, merge
from worlds.materials import MATERIALS
from worlds.placement import clearance, edge
from worlds.world import Part

FACADES = ("brick", "glass", "concrete")


class BuildingRow(BaseModel):
    """A row of buildings along one side of the route."""

    model_config = ConfigDict(extra="forbid")

    side: Literal["left", "right"] = Field(..., description="side of the route, looking along it")
    start_m: float = Field(..., description="route station where the row starts, m")
    end_m: float = Field(..., description="route station where the row ends, m")
    setback_m: float = Field(10.0, ge=0.0, le=2000.0, description="distance from the channel edge to the building fronts, m")
    ground_m: float = Field(3.0, ge=0.0, le=50.0, description="ground height above the water where the buildings stand, m")
    height_m: tuple[float, float] = Field((12.0, 30.0), description="range of building heights above the ground, m")
    frontage_m: tuple[float, float] = Field((15.0, 40.0), description="range of building lengths along the route, m")
    depth_m: tuple[float, float] = Field((12.0, 30.0), description="range of building depths away from the channel, m")
    gap_m: tuple[float, float] = Field((3.0, 15.0), description="range of gaps between neighbouring buildings, m")
    rows: int = Field(1, ge=1, le=10, description="number of blocks one behind the other (streets of gap_m between them)")

    @model_validator(mode="after")
    def _ranges(self) -> BuildingRow:
        for key in ("height_m", "frontage_m", "depth_m", "gap_m"):
            lo, hi = getattr(self, key)
            if not 0.0 <= lo <= hi or (key != "gap_m" and lo <= 0):
                raise ValueError(f"{key}: need 0 < min <= max, got ({lo}, {hi})")
        if self.end_m <= self.start_m:
            raise ValueError(f"end_m={self.end_m} must be greater than start_m={self.start_m}")
        return self


def build_buildings(rows: list[BuildingRow], line: Centerline, seed: int, keep_clear: list[tuple[float, float]]) -> list[Part]:
    """One part per facade material holding every building of that material."""
    rng = stream(seed, "worlds.buildings")
    by_material: dict[str, list] = {m: [] for m in FACADES}
    for row in rows:
        sign = line.side_sign(row.side)
        edge_line = edge(line, row.side)
        cursor = max(row.start_m, float(line.s[0]))
        while True:
            front = rng.uniform(*row.frontage_m)
            gap = rng.uniform(*row.gap_m)
            if cursor + front > min(row.end_m, float(line.s[-1])):
                break
            sc = cursor + front / 2
            cursor += front + gap
            xy, nl, wl, wr = line.sample(np.array([sc]))
            width = (wl if row.side == "left" else wr)[0]
            along = np.array([nl[0, 1], -nl[0, 0]])
            out = sign * nl[0]
            offset = width + row.setback_m
            for _ in range(row.rows):
                depth = rng.uniform(*row.depth_m)
                height = rng.uniform(*row.height_m)
                material = FACADES[int(rng.integers(len(FACADES)))]
                centre = xy[0] + out * (offset + depth / 2)
                offset += depth + rng.uniform(*row.gap_m) + 6.0
                if any(a - front / 2 - 5.0 <= sc <= b + front / 2 + 5.0 for a, b in keep_clear):
                    continue
                corners = centre + np.array([[i * front / 2, j * depth / 2] for i in (-1, 1) for j in (-1, 1)]) @ np.stack([along, out])
                if clearance(edge_line, corners).min() < 0.5 * row.setback_m:
                    continue
                z0 = row.ground_m - 1.0
                by_material[material].append(box(np.r_[centre, z0 + (height + 1.0) / 2], along, (front, depth, height + 1.0)))
    return [Part(f"buildings_{m}", "building", MATERIALS[m], merge(meshes)) for m, meshes in by_material.items() if meshes]
