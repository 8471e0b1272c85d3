"""The channel along the route: water surface, and per side and stretch walls, quays or natural banks.

Each edge is a cross-section profile (offsets outward from the channel edge, heights above the
water) swept along the route; the channel edge on each side lies `route.left_m` / `route.right_m`
from the route. The channel continues straight `end_extension_m` beyond both route ends so the
vessel never sees the world's edge at the start or end of its run.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import trimesh
from pydantic import BaseModel, ConfigDict, Field, field_validator

from worlds.geometry import UP, adaptive_indices, merge, mesh_from, orient, strip, untangle
from worlds.materials import MATERIALS
from worlds.route import Route
from worlds.world import Part

EdgeType = Literal["wall", "quay", "bank"]
DEFAULT_MATERIAL = {"wall": "concrete", "quay": "granite", "bank": "grass"}


def _check_material(value: str) -> str:
    if value and value not in MATERIALS:
        raise ValueError(f"unknown material {value!r} (one of {', '.join(sorted(MATERIALS))})")
    return value


class EdgeStyle(BaseModel):
    """Cross-section of one channel edge."""

    model_config = ConfigDict(extra="forbid")

    type: EdgeType = Field("wall", description="wall: vertical canal wall; quay: wall with a paved deck behind; bank: sloped natural bank")
    top_m: float = Field(3.0, gt=0.0, le=30.0, description="height of the edge top (and the ground behind it) above the water, m")
    below_m: float = Field(2.0, gt=0.0, le=20.0, description="depth below the water surface the wall or bank toe reaches, m")
    material: str = Field("", description="material of the wall face or bank slope; empty = concrete (wall), granite (quay), grass (bank)")
    slope: float = Field(0.4, gt=0.05, le=5.0, description="bank rise over run (0.4 = 1:2.5), used by type 'bank'")
    quay_deck_m: float = Field(8.0, gt=0.0, le=100.0, description="width of the paved quay deck behind a quay wall, m")
    ground_width_m: float = Field(60.0, gt=0.0, le=2000.0, description="width of the flat ground behind the edge top, m (buildings stand on it)")

    @field_validator("material")
    @classmethod
    def _known_material(cls, value: str) -> str:
        return _check_material(value)

    def profile(self) -> list[tuple[float, float, str, str, str]]:
        """The cross-section as points (offset outward from the edge, z, role, kind, material).

        The first point only starts the polyline (empty role); every later point ends a segment
        whose surface has that role (part name), part kind and material.
        """
        face = self.material or DEFAULT_MATERIAL[self.type]
        if self.type == "wall":
            pts = [(0.0, -self.below_m, "", "", ""), (0.0, self.top_m, "wall", "wall", face)]
            back = 0.0
        elif self.type == "quay":
            pts = [
                (0.0, -self.below_m, "", "", ""),
                (0.0, self.top_m, "quay", "quay", face),
                (self.quay_deck_m, self.top_m, "quaydeck", "quay", "concrete"),
            ]
            back = self.quay_deck_m
        else:
            pts = [(-self.below_m / self.slope, -self.below_m, "", "", ""), (self.top_m / self.slope, self.top_m, "bank", "bank", face)]
            back = self.top_m / self.slope
        pts.append((back + self.ground_width_m, self.top_m, "ground", "bank", "grass" if self.type == "bank" else "soil"))
        return pts


class EdgeStretch(EdgeStyle):
    """An edge style applied on one side between two route stations (overrides the default)."""

    side: Literal["left", "right"] = Field(..., description="side of the route, looking along it")
    start_m: float = Field(..., description="route station where the stretch starts, m (may be < 0: the extension before the route)")
    end_m: float = Field(..., description="route station where the stretch ends, m")


class ChannelParams(BaseModel):
    """How the channel around the route is built."""

    model_config = ConfigDict(extra="forbid")

    left: EdgeStyle = Field(default_factory=EdgeStyle, description="default edge on the left side of the route")
    right: EdgeStyle = Field(default_factory=EdgeStyle, description="default edge on the right side of the route")
    stretches: list[EdgeStretch] = Field(default_factory=list, description="per-side station ranges with another edge style; later ones win")
    water_margin_m: float = Field(8.0, gt=0.0, description="how far the water surface reaches beyond each edge (under walls and banks), m")
    end_extension_m: float = Field(150.0, ge=0.0, description="straight channel continued beyond each route end, m")
    max_turn_deg: float = Field(1.0, gt=0.0, le=30.0, description="sampling: new cross-section whenever the route heading turned this much")
    max_step_m: float = Field(8.0, gt=0.0, le=500.0, description="sampling: longest step between cross-sections on straights, m")


@dataclass(frozen=True)
class Centerline:
    """The route extended straight beyond both ends, as arrays over station s (may be negative)."""

    s: np.ndarray
    xy: np.ndarray
    heading: np.ndarray
    left: np.ndarray
    right: np.ndarray

    @classmethod
    def of(cls, route: Route, extension_m: float) -> Centerline:
        """Extend `route` by `extension_m` at each end along its end headings (2 m steps)."""
        n = max(int(np.ceil(extension_m / 2.0)), 1) if extension_m > 0 else 0
        ext = np.linspace(extension_m, 0.0, n, endpoint=False)[::-1] if n else np.zeros(0)
        d0 = np.array([np.cos(route.heading[0]), np.sin(route.heading[0])])
        d1 = np.array([np.cos(route.heading[-1]), np.sin(route.heading[-1])])
        head = route.xy[0] - ext[::-1, None] * d0
        tail = route.xy[-1] + ext[:, None] * d1
        return cls(
            s=np.r_[-ext[::-1], route.s, route.length + ext],
            xy=np.r_[head, route.xy, tail],
            heading=np.r_[np.full(n, route.heading[0]), route.heading, np.full(n, route.heading[-1])],
            left=np.r_[np.full(n, route.left_m[0]), route.left_m, np.full(n, route.left_m[-1])],
            right=np.r_[np.full(n, route.right_m[0]), route.right_m, np.full(n, route.right_m[-1])],
        )

    def sample(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Position (N,2), left normal (N,2), left and right widths at stations s (interpolated)."""
        xy = np.stack([np.interp(s, self.s, self.xy[:, 0]), np.interp(s, self.s, self.xy[:, 1])], 1)
        h = np.interp(s, self.s, self.heading)
        return xy, np.stack([-np.sin(h), np.cos(h)], 1), np.interp(s, self.s, self.left), np.interp(s, self.s, self.right)

    def width(self, side: str) -> np.ndarray:
        return self.left if side == "left" else self.right

    def side_sign(self, side: str) -> float:
        return 1.0 if side == "left" else -1.0


def _stations(line: Centerline, start: float, end: float, params: ChannelParams) -> np.ndarray:
    """Cross-section stations between start and end: adaptive in heading, exact at both ends."""
    keep = adaptive_indices(line.heading, line.s, np.radians(params.max_turn_deg), params.max_step_m)
    s = line.s[keep]
    return np.unique(np.r_[start, s[(s > start) & (s < end)], end])


def _intervals(side: str, params: ChannelParams, s0: float, s1: float) -> list[tuple[float, float, EdgeStyle]]:
    """Split [s0, s1] into maximal station intervals of one edge style on `side`."""
    default: EdgeStyle = getattr(params, side)
    own = [st for st in params.stretches if st.side == side]
    cuts = np.unique(np.clip([s0, s1, *[st.start_m for st in own], *[st.end_m for st in own]], s0, s1))
    out: list[tuple[float, float, EdgeStyle]] = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        mid = 0.5 * (a + b)
        style = default
        for st in own:
            if st.start_m <= mid <= st.end_m:
                style = EdgeStyle(**st.model_dump(exclude={"side", "start_m", "end_m"}))
        if out and out[-1][2] == style:
            out[-1] = (out[-1][0], b, style)
        else:
            out.append((a, b, style))
    return out


def edge_summary(route: Route, params: ChannelParams) -> list[dict]:
    """Json-able edge stretches along the route: side, station range, type, height, material."""
    out = []
    for side in ("left", "right"):
        for a, b, style in _intervals(side, params, 0.0, route.length):
            out.append(
                {
                    "side": side,
                    "start_m": float(a),
                    "end_m": float(b),
                    "type": style.type,
                    "top_m": style.top_m,
                    "material": style.material or DEFAULT_MATERIAL[style.type],
                }
            )
    return out


def ground_height(params: ChannelParams, side: str, s: np.ndarray, offset: np.ndarray) -> np.ndarray:
    """Height above the water of the edge profile on `side` at stations s, `offset` m outward from
    the channel edge (on a bank's slope, its top or the flat ground behind any edge)."""
    s, offset = np.asarray(s, float), np.asarray(offset, float)
    z = np.zeros(len(s))
    if not len(s):
        return z
    for a, b, style in _intervals(side, params, float(s.min()) - 1.0, float(s.max()) + 1.0):
        prof = style.profile()
        sel = (s >= a) & (s <= b)
        z[sel] = np.interp(offset[sel], [p[0] for p in prof], [p[1] for p in prof])
    return z


def _offset_line(line: Centerline, side: str, s: np.ndarray, offset: float) -> np.ndarray:
    """Edge-relative offset line on `side` at stations s, untangled at tight inner bends."""
    xy, nl, wl, wr = line.sample(s)
    width = wl if side == "left" else wr
    dist = np.maximum(width + offset, 0.05)
    return untangle(xy + line.side_sign(side) * nl * dist[:, None])


def build_channel(route: Route, params: ChannelParams) -> list[Part]:
    """Water surface plus, on each side, edge faces and ground, grouped into parts by role and material.

    Each offset line is computed and untangled over the whole side, then cut into the stretches,
    so a loop that spans a stretch boundary is trimmed too.
    """
    line = Centerline.of(route, params.end_extension_m)
    s0, s1 = float(line.s[0]), float(line.s[-1])
    groups: dict[tuple[str, str, str, str], list] = {}
    for side in ("left", "right"):
        intervals = _intervals(side, params, s0, s1)
        s_all = np.unique(np.concatenate([_stations(line, a, b, params) for a, b, _ in intervals]))
        _, nl_all, _, _ = line.sample(s_all)
        offset_lines: dict[float, np.ndarray] = {}
        for a, b, style in intervals:
            idx = np.flatnonzero((s_all >= a - 1e-9) & (s_all <= b + 1e-9))
            s, nl = s_all[idx], nl_all[idx]
            outward = np.c_[line.side_sign(side) * nl, np.zeros(len(s))]
            toward = UP - outward
            prof = style.profile()
            for off, *_ in prof:
                if off not in offset_lines:
                    offset_lines[off] = _offset_line(line, side, s_all, off)
            lines = [offset_lines[off][idx] for off, *_ in prof]
            for k in range(1, len(prof)):
                _, z1, role, kind, mat = prof[k]
                z0 = prof[k - 1][1]
                seg = np.stack([np.c_[lines[k - 1], np.full(len(s), z0)], np.c_[lines[k], np.full(len(s), z1)]])
                mesh = strip(seg)
                if len(mesh.faces):
                    groups.setdefault((side, role, kind, mat), []).append(_oriented(mesh, seg, toward))
            along = np.c_[nl[:, 1], -nl[:, 0], np.zeros(len(s))]
            for end_idx, facing in ((0, -along[0]), (-1, along[-1])):
                cap = orient(_cap(prof, [ln[end_idx] for ln in lines], style.below_m), facing)
                groups.setdefault((side, prof[1][2], prof[1][3], prof[1][4]), []).append(cap)
    water = _water(line, params, s0, s1)
    parts = [Part("water", "water", MATERIALS["water"], water)]
    for (side, role, kind, mat), meshes in groups.items():
        parts.append(Part(f"{side}_{role}_{mat}", kind, MATERIALS[mat], merge(meshes)))
    return parts


def _oriented(mesh: trimesh.Trimesh, seg: np.ndarray, toward: np.ndarray) -> trimesh.Trimesh:
    """Orient a two-line strip's faces toward the water and sky (`toward` given per station)."""
    centroid = np.asarray(mesh.triangles_center)[:, :2]
    base = seg[0, :, :2]
    nearest = np.argmin(np.linalg.norm(centroid[:, None, :] - base[None, :, :], axis=2), axis=1)
    return orient(mesh, toward[nearest])


def _cap(prof: list[tuple], end_pts: list[np.ndarray], below_m: float) -> trimesh.Trimesh:
    """Vertical end face closing a profile (fan over its convex cross-section polygon)."""
    xyz = [np.r_[p, z] for p, (_, z, *_r) in zip(end_pts, prof)]
    xyz.append(np.r_[end_pts[-1], -below_m])
    v = np.array(xyz)
    faces = np.array([[0, i, i + 1] for i in range(1, len(v) - 1)])
    return mesh_from(v, faces)


def _water(line: Centerline, params: ChannelParams, s0: float, s1: float) -> trimesh.Trimesh:
    """Flat water at z = 0 from beyond the right edge to beyond the left edge, normals up."""
    s = _stations(line, s0, s1, params)
    xy, _, _, _ = line.sample(s)
    left = _offset_line(line, "left", s, params.water_margin_m)
    right = _offset_line(line, "right", s, params.water_margin_m)
    seg = np.stack([np.c_[right, np.zeros(len(s))], np.c_[xy, np.zeros(len(s))], np.c_[left, np.zeros(len(s))]])
    return orient(strip(seg), UP)
