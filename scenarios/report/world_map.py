"""The world under the report's map: each part's mesh projected onto the x-y plane, cheaply.

A part's triangles that face up or down (|normal z| > FLAT_NZ) are filled as they project (their union is the part's
footprint: banks, quay decks, bridge decks, buildings' roofs); its vertical triangles project to line segments, drawn
as outlines for the kinds that are walls (a canal wall is a vertical sheet with no top). Only the triangles near the
map's extent are kept, and the vegetation (thousands of crown facets) is left out. The world comes from the resolved
scenario (`worlds.load` of its world and world_params: a disk-cached preset loads in milliseconds).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.collections import LineCollection, PolyCollection
from matplotlib.patches import Patch

FLAT_NZ = 0.05
"""A triangle with |normal z| above this is filled; at or below it is vertical and projects to a segment."""
OUTLINED = ("wall", "quay", "lock_wall", "lock_gate")
"""Kinds whose vertical faces are drawn as lines (the water's edge)."""
LEFT_OUT = ("tree", "foliage")
"""Kinds not drawn: trunks and crowns would bury the tracks."""


@dataclass(frozen=True)
class Style:
    """How a group of part kinds is drawn: legend label, fill and outline colours, drawing order, opacity."""

    label: str
    fill: str
    line: str
    zorder: float
    alpha: float = 1.0


STYLES = {
    "water": Style("water", "#dcecf7", "#dcecf7", 0.1),
    "bank": Style("bank, ground", "#e7dfc3", "#e7dfc3", 0.2),
    "building": Style("building", "#b5b5b5", "#b5b5b5", 0.4),
    "wall": Style("wall (line), quay deck, lock", "#cfcfcf", "#303030", 0.6),
    "bridge": Style("bridge (deck, girders, arches)", "#8c7b6b", "#8c7b6b", 0.8, 0.4),
    "pier": Style("pier, pile", "#2f2f2f", "#2f2f2f", 0.9),
    "boat": Style("dock, pontoon, moored boat", "#a0522d", "#a0522d", 0.9, 0.8),
    "other": Style("other", "#999999", "#666666", 0.5),
}
"""Styles by group; every colour differs from the tracks', windows' and GPS fixes' (scenarios.report.plots)."""
GROUPS = {
    "water": "water",
    "bank": "bank",
    "building": "building",
    "wall": "wall",
    "quay": "wall",
    "lock_wall": "wall",
    "lock_gate": "wall",
    "bridge_deck": "bridge",
    "girder": "bridge",
    "arch": "bridge",
    "pier": "pier",
    "pile": "pier",
    "dock": "boat",
    "pontoon": "boat",
    "moored_boat": "boat",
}
"""The style group of each part kind (worlds.world.PART_KINDS; 'other' for the rest)."""


@dataclass(frozen=True)
class Footprint:
    """One part kind's projection near the map: filled triangles (N, 3, 2) and outline segments (M, 2, 2), metres ENU."""

    kind: str
    fill: np.ndarray
    lines: np.ndarray

    @property
    def style(self) -> Style:
        return STYLES[GROUPS.get(self.kind, "other")]


def load(info: dict):
    """The world of a resolved scenario (a dict of scenario.toml), or None when it names none or cannot be loaded."""
    import worlds

    name = info.get("world")
    if not name:
        return None
    try:
        return worlds.load(name, **(info.get("world_params") or {}))
    except (ValueError, OSError, TypeError):  # a mesh file moved since the run, parameters of another version
        return None


def footprints(world, extent: tuple[float, float, float, float]) -> list[Footprint]:
    """The projections of the world's parts that reach into extent (xmin, xmax, ymin, ymax), merged per kind."""
    x0, x1, y0, y1 = extent
    by_kind: dict[str, tuple[list[np.ndarray], list[np.ndarray]]] = {}
    for part in world.parts:
        if part.kind in LEFT_OUT:
            continue
        triangles = np.asarray(part.mesh.vertices)[np.asarray(part.mesh.faces)][:, :, :2]
        near = (triangles[:, :, 0].max(axis=1) >= x0) & (triangles[:, :, 0].min(axis=1) <= x1)
        near &= (triangles[:, :, 1].max(axis=1) >= y0) & (triangles[:, :, 1].min(axis=1) <= y1)
        if not near.any():
            continue
        flat = np.abs(np.asarray(part.mesh.face_normals)[:, 2]) > FLAT_NZ
        fills, lines = by_kind.setdefault(part.kind, ([], []))
        fills.append(triangles[near & flat].astype(np.float32))
        if part.kind in OUTLINED or not flat.any():
            lines.append(_segments(triangles[near & ~flat]).astype(np.float32))
    return [
        Footprint(kind, np.concatenate(fills) if fills else np.zeros((0, 3, 2)), np.concatenate(lines) if lines else np.zeros((0, 2, 2)))
        for kind, (fills, lines) in by_kind.items()
    ]


def _segments(triangles: np.ndarray) -> np.ndarray:
    """(N, 2, 2): each vertical triangle's projection, a segment between its two projected corners furthest apart."""
    if not len(triangles):
        return np.zeros((0, 2, 2))
    pairs = np.array([(0, 1), (1, 2), (0, 2)])
    lengths = np.linalg.norm(triangles[:, pairs[:, 0]] - triangles[:, pairs[:, 1]], axis=2)
    longest = pairs[np.argmax(lengths, axis=1)]
    rows = np.arange(len(triangles))
    return np.stack([triangles[rows, longest[:, 0]], triangles[rows, longest[:, 1]]], axis=1)


def draw(ax, prints: list[Footprint]) -> list[Patch]:
    """Draw the footprints under everything else on the axis; returns one legend patch per style drawn."""
    drawn: dict[str, Style] = {}
    for footprint in prints:
        style = footprint.style
        if len(footprint.fill):
            ax.add_collection(
                PolyCollection(footprint.fill, facecolors=style.fill, edgecolors=style.fill, linewidths=0.3, alpha=style.alpha, zorder=style.zorder)
            )
        if len(footprint.lines):
            ax.add_collection(LineCollection(footprint.lines, colors=style.line, linewidths=1.4, alpha=style.alpha, zorder=style.zorder + 0.05))
        if len(footprint.fill) or len(footprint.lines):
            drawn[style.label] = style
    order = list(STYLES.values())
    return [Patch(facecolor=s.fill, edgecolor=s.line, alpha=s.alpha, label=s.label) for s in sorted(drawn.values(), key=order.index)]
