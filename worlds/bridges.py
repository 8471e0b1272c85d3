"""Bridges across the channel: a beam bridge on piers, a masonry or steel-rib arch bridge, a steel girder/truss bridge.

A bridge sits at route station `station_m`; its axis crosses the route at `crossing_angle_deg`
from the route's normal (0 = square crossing). Local frame: origin at the route point, u along
the bridge axis (positive toward the route's left bank), v across the deck, z up. Piers stand at
u = (k + 1/2) * pier_spacing_m, so the route always passes mid-span between two piers.
`deck_height_m` is the clearance: the height above the water of the lowest structure over the
route (deck underside for slab beam bridges, the girders' bottom flanges for girder beam and truss
bridges, the crown's intrados of the vault or of the ribs for arch bridges).

What is under a deck decides what a LiDAR can register there. A flat slab on piers parallel to the
route, or a masonry vault, is a tunnel: nothing in it fixes the motion along the route. Spans of
20-50 m, as on the Charles, are carried by girders or arch ribs across the route instead, whose
webs face along it (girder_spacing_m, rib_spacing_m).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
import trimesh
from numpy.typing import ArrayLike
from pydantic import BaseModel, ConfigDict, Field, model_validator

from worlds.geometry import UP, box, merge, orient, pipe, strip
from worlds.materials import MATERIALS
from worlds.route import Route
from worlds.world import Part

BridgeType = Literal["beam", "arch", "truss"]


class BridgeSpec(BaseModel):
    """One bridge: type, placement along the route, and dimensions in metres."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(..., min_length=1, description="unique name, used in part names and world.params['structures']")
    type: BridgeType = Field(
        ...,
        description="beam (deck on piers, on girders if girder_spacing_m > 0), arch (masonry vaults, or steel ribs "
        "if rib_spacing_m > 0, on piers) or truss (steel girders, truss and pipes)",
    )
    station_m: float = Field(..., description="route arc length where the bridge axis crosses the route, m")
    crossing_angle_deg: float = Field(0.0, ge=-60.0, le=60.0, description="angle between the bridge axis and the route's normal, deg (0 = square)")
    deck_height_m: float = Field(6.0, gt=0.5, le=60.0, description="clearance above the water of the lowest structure over the route, m")
    deck_width_m: float = Field(
        20.0, gt=0.0, le=200.0, description="width of the deck across its axis, m (about the along-route length of the GPS shadow)"
    )
    deck_thickness_m: float = Field(1.2, gt=0.0, le=10.0, description="thickness of the deck slab (beam) or road deck (arch, truss), m")
    length_m: float | None = Field(None, gt=0.0, description="overall length along the axis; None = channel width along the axis plus both abutments")
    abutment_m: float = Field(15.0, ge=0.0, le=200.0, description="how far the deck reaches onto land beyond each channel edge, m")
    pier_spacing_m: float = Field(30.0, gt=2.0, le=1000.0, description="distance between pier centres along the axis (the span), m")
    pier_width_m: float = Field(2.0, gt=0.0, le=30.0, description="pier thickness along the bridge axis, m")
    pier_base_m: float = Field(3.0, gt=0.0, le=50.0, description="depth below the water the piers reach, m")
    parapet_m: float = Field(1.1, ge=0.0, le=5.0, description="parapet / railing height on both deck edges, m")
    arch_spring_m: float = Field(1.5, ge=0.0, le=30.0, description="arch: height above the water where arches spring from the piers, m")
    truss_height_m: float = Field(5.0, ge=0.0, le=40.0, description="truss: height of the through truss above the deck, m (0 = girders only)")
    girder_depth_m: float = Field(1.6, gt=0.2, le=10.0, description="beam with girders, truss: depth of the steel girders under the road deck, m")
    girder_spacing_m: float = Field(
        0.0,
        ge=0.0,
        le=10.0,
        description="beam: spacing across the deck of steel I-girders along the bridge axis under "
        "the slab, one under the route's centreline, m (0 = a flat slab soffit)",
    )
    rib_spacing_m: float = Field(
        0.0,
        ge=0.0,
        le=20.0,
        description="arch: spacing across the deck of steel arch ribs carrying the deck on spandrel "
        "columns, one under the route's centreline, m (0 = a masonry vault with spandrel walls)",
    )
    rib_depth_m: float = Field(1.5, gt=0.2, le=10.0, description="arch with ribs: depth of each rib, m")
    panel_m: float = Field(
        6.0, gt=1.0, le=50.0, description="truss: panel length of the truss and bracing; arch with ribs: spacing of the spandrel columns, m"
    )

    @model_validator(mode="after")
    def _piers_fit(self) -> BridgeSpec:
        if self.pier_width_m >= self.pier_spacing_m - 2.0:
            raise ValueError(f"pier_width_m={self.pier_width_m} must be at least 2 m less than pier_spacing_m={self.pier_spacing_m}")
        return self

    def frame(self, route: Route) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Origin (2,), unit axis u (2,) and unit v (2,) of the bridge in ENU."""
        if not 0.0 < self.station_m < route.length:
            raise ValueError(f"bridge {self.name!r}: station_m={self.station_m} is outside the route (0, {route.length:.1f})")
        xy, heading = route.at(self.station_m)
        ang = heading + np.pi / 2 + np.radians(self.crossing_angle_deg)
        u = np.array([np.cos(ang), np.sin(ang)])
        return xy, u, np.array([u[1], -u[0]])

    def extent(self, route: Route) -> tuple[float, float, float, float]:
        """(u_min, u_max) of the deck and (u_right_edge, u_left_edge) of the channel along the axis."""
        i = int(np.clip(np.searchsorted(route.s, self.station_m), 0, len(route.s) - 1))
        cos = np.cos(np.radians(self.crossing_angle_deg))
        left, right = route.left_m[i] / cos, route.right_m[i] / cos
        if self.length_m is None:
            return -right - self.abutment_m, left + self.abutment_m, -right, left
        mid = 0.5 * (left - right)
        if self.length_m < left + right:
            raise ValueError(f"bridge {self.name!r}: length_m={self.length_m} is shorter than the channel ({left + right:.1f} m along its axis)")
        return mid - self.length_m / 2, mid + self.length_m / 2, -right, left

    def piers_u(self, route: Route) -> np.ndarray:
        """Pier centres along the axis: mid-span at the route, only those standing in the water."""
        _, _, edge_r, edge_l = self.extent(route)
        k = np.arange(np.floor(edge_r / self.pier_spacing_m) - 1, np.ceil(edge_l / self.pier_spacing_m) + 1)
        u = (k + 0.5) * self.pier_spacing_m
        half = self.pier_width_m / 2
        return u[(u - half > edge_r) & (u + half < edge_l)]


def _world(origin: np.ndarray, u: np.ndarray, v: np.ndarray, local: ArrayLike) -> np.ndarray:
    """Local (u, v, z) points (..., 3) to ENU."""
    local = np.asarray(local, float)
    xy = origin + local[..., :1] * u + local[..., 1:2] * v
    return np.concatenate([xy, local[..., 2:3]], axis=-1)


def _local_box(origin, u, v, center_uvz, size) -> trimesh.Trimesh:
    """Upright box given in the bridge frame (size along u, v, z)."""
    return box(_world(origin, u, v, np.asarray(center_uvz, float)), u, size)


def _piers(spec: BridgeSpec, route: Route, origin, u, v, top: float) -> list[trimesh.Trimesh]:
    """Pier boxes; ValueError when the route (curving or crossing at an angle) passes within 1 m of one."""
    length = spec.deck_width_m + 2.0
    z0 = -spec.pier_base_m
    near = np.abs(route.s - spec.station_m) < length + 20.0
    rel = route.xy[near] - origin
    pu, pv = rel @ u, rel @ v
    for c in spec.piers_u(route):
        gap = np.abs(pu - c)[np.abs(pv) <= length / 2]
        if len(gap) and gap.min() < spec.pier_width_m / 2 + 1.0:
            raise ValueError(
                f"bridge {spec.name!r}: pier_spacing_m={spec.pier_spacing_m} puts a pier within 1 m of the route "
                f"(crossing_angle_deg={spec.crossing_angle_deg}, deck_width_m={spec.deck_width_m})"
            )
    return [_local_box(origin, u, v, (pu, 0.0, 0.5 * (z0 + top)), (spec.pier_width_m, length, top - z0)) for pu in spec.piers_u(route)]


def _deck(spec: BridgeSpec, origin, u, v, u0: float, u1: float, z_bottom: float) -> list[trimesh.Trimesh]:
    """Road deck slab with parapets on both edges."""
    w, t = spec.deck_width_m, spec.deck_thickness_m
    out = [_local_box(origin, u, v, (0.5 * (u0 + u1), 0.0, z_bottom + t / 2), (u1 - u0, w, t))]
    if spec.parapet_m > 0:
        for side in (-1, 1):
            out.append(
                _local_box(origin, u, v, (0.5 * (u0 + u1), side * (w / 2 - 0.15), z_bottom + t + spec.parapet_m / 2), (u1 - u0, 0.3, spec.parapet_m))
            )
    return out


def _abutments(spec: BridgeSpec, origin, u, v, ext: tuple[float, float, float, float], z_top: float) -> list[trimesh.Trimesh]:
    """Solid blocks on land from each channel edge to the deck ends, up to the deck."""
    u0, u1, er, el = ext
    out = []
    for a, b in ((u0, er - 1.0), (el + 1.0, u1)):
        if b - a > 0.1:
            out.append(_local_box(origin, u, v, (0.5 * (a + b), 0.0, 0.5 * (z_top - 2.0)), (b - a, spec.deck_width_m, z_top + 2.0)))
    return out


def _across(width: float, spacing: float, margin: float) -> np.ndarray:
    """Offsets across a deck of `width`, `spacing` apart with one at 0, at least `margin` inside the edges."""
    k = np.floor((width / 2 - margin) / spacing)
    return np.arange(-k, k + 1) * spacing


def _i_girders(origin, u, v, u0: float, u1: float, across: np.ndarray, z_bottom: float, depth: float) -> list[trimesh.Trimesh]:
    """Steel I-girders along the bridge axis from u0 to u1 at each offset `across`: web and both flanges."""
    mid, length = 0.5 * (u0 + u1), u1 - u0
    out = []
    for gv in across:
        out.append(_local_box(origin, u, v, (mid, gv, z_bottom + 0.02), (length, 0.6, 0.04)))
        out.append(_local_box(origin, u, v, (mid, gv, z_bottom + depth / 2), (length, 0.03, depth - 0.08)))
        out.append(_local_box(origin, u, v, (mid, gv, z_bottom + depth - 0.02), (length, 0.6, 0.04)))
    return out


def build_beam(spec: BridgeSpec, route: Route) -> list[Part]:
    """Concrete slab deck on rectangular piers, on steel I-girders if girder_spacing_m > 0."""
    origin, u, v = spec.frame(route)
    ext = spec.extent(route)
    h = spec.deck_height_m
    concrete = MATERIALS["concrete"]
    parts = []
    slab = h
    if spec.girder_spacing_m > 0:
        across = _across(spec.deck_width_m, spec.girder_spacing_m, 0.5)
        girders = _i_girders(origin, u, v, ext[0], ext[1], across, h, spec.girder_depth_m)
        parts.append(Part(f"{spec.name}_girders", "girder", MATERIALS["steel"], merge(girders)))
        slab = h + spec.girder_depth_m
    parts.append(Part(f"{spec.name}_deck", "bridge_deck", concrete, merge(_deck(spec, origin, u, v, ext[0], ext[1], slab))))
    piers = _piers(spec, route, origin, u, v, h)
    if piers:
        parts.append(Part(f"{spec.name}_piers", "pier", concrete, merge(piers)))
    abut = _abutments(spec, origin, u, v, ext, slab)
    if abut:
        parts.append(Part(f"{spec.name}_abutments", "pier", concrete, merge(abut)))
    return parts


def _arch_curve(a: float, b: float, spring: float, crown: float, n: int = 16) -> tuple[np.ndarray, np.ndarray]:
    """(u, z) of an elliptical intrados between pier faces a < b, from `spring` to `crown` at mid-span."""
    uc, half = 0.5 * (a + b), 0.5 * (b - a)
    uu = uc + half * np.cos(np.linspace(np.pi, 0.0, n + 1))
    zz = spring + (crown - spring) * np.sqrt(np.clip(1.0 - ((uu - uc) / half) ** 2, 0.0, 1.0))
    uu[n // 2], zz[n // 2] = uc, crown
    return uu, zz


def _swept(origin, u, v, uu: np.ndarray):
    """(vv, z) -> ENU points of an arch curve at stations uu along the axis, at offset vv across the deck and heights z."""
    return lambda vv, z: _world(origin, u, v, np.c_[uu, np.full(len(uu), vv), z])


def _rib_span(
    origin, u, v, a: float, b: float, spring: float, crown: float, depth: float, across: np.ndarray, column_every: float, deck_bottom: float
) -> list[trimesh.Trimesh]:
    """Steel arch ribs 0.8 m wide between pier faces a < b at each offset `across` (their sides face
    along the route), and 0.5 m square spandrel columns from each rib up to the deck every column_every m."""
    uu, zz = _arch_curve(a, b, spring, crown)
    curve = _swept(origin, u, v, uu)
    out = []
    for c in across:
        lo, hi = c - 0.4, c + 0.4
        out.append(orient(strip(np.stack([curve(lo, zz), curve(hi, zz)])), -UP))
        out.append(orient(strip(np.stack([curve(lo, zz + depth), curve(hi, zz + depth)])), UP))
        for side, vv in ((-1, lo), (1, hi)):
            out.append(orient(strip(np.stack([curve(vv, zz), curve(vv, zz + depth)])), np.r_[side * v, 0.0]))
        k = np.floor((0.5 * (b - a) - 0.5) / column_every)
        for cu in 0.5 * (a + b) + np.arange(-k, k + 1) * column_every:
            z0 = float(np.interp(cu, uu, zz)) + depth
            if deck_bottom - z0 > 0.5:
                out.append(_local_box(origin, u, v, (cu, c, 0.5 * (z0 + deck_bottom)), (0.5, 0.5, deck_bottom - z0)))
    return out


def _arch_span(origin, u, v, a: float, b: float, spring: float, crown: float, top: float, half_w: float) -> list[trimesh.Trimesh]:
    """Elliptical masonry vault between pier faces a < b (intrados from `spring` to `crown`, facing down) and
    its spandrel walls up to `top` (facing out of the bridge)."""
    uu, zz = _arch_curve(a, b, spring, crown)
    curve = _swept(origin, u, v, uu)
    vault = orient(strip(np.stack([curve(-half_w, zz), curve(half_w, zz)])), -UP)
    sides = [orient(strip(np.stack([curve(s * half_w, zz), curve(s * half_w, np.full(len(uu), top))])), np.r_[s * v, 0.0]) for s in (-1, 1)]
    return [vault, *sides]


def build_arch(spec: BridgeSpec, route: Route) -> list[Part]:
    """Piers carrying elliptical masonry vaults with spandrel walls (granite), or open-spandrel steel
    ribs (rib_spacing_m > 0), road deck on top."""
    origin, u, v = spec.frame(route)
    ext = spec.extent(route)
    crown, spring = spec.deck_height_m, min(spec.arch_spring_m, spec.deck_height_m - 0.5)
    ribbed = spec.rib_spacing_m > 0
    top = crown + (spec.rib_depth_m + 0.3 if ribbed else 0.8)
    granite = MATERIALS["granite"]
    piers_u = spec.piers_u(route)
    faces = np.r_[ext[2], np.ravel(np.c_[piers_u - spec.pier_width_m / 2, piers_u + spec.pier_width_m / 2]), ext[3]]
    arches = []
    for a, b in zip(faces[0::2], faces[1::2]):
        if ribbed:
            arches += _rib_span(
                origin, u, v, a, b, spring, crown, spec.rib_depth_m, _across(spec.deck_width_m, spec.rib_spacing_m, 0.5), spec.panel_m, top
            )
        else:
            arches += _arch_span(origin, u, v, a, b, spring, crown, top, spec.deck_width_m / 2)
    parts = [
        Part(f"{spec.name}_arches", "arch", MATERIALS["steel"] if ribbed else granite, merge(arches)),
        Part(f"{spec.name}_deck", "bridge_deck", MATERIALS["concrete"], merge(_deck(spec, origin, u, v, ext[0], ext[1], top))),
    ]
    piers = _piers(spec, route, origin, u, v, top)
    if piers:
        parts.append(Part(f"{spec.name}_piers", "pier", granite, merge(piers)))
    parts.append(Part(f"{spec.name}_abutments", "pier", granite, merge(_abutments(spec, origin, u, v, ext, top))))
    return parts


def build_truss(spec: BridgeSpec, route: Route) -> list[Part]:
    """Steel I-girders under a concrete deck, cross bracing and utility pipes below, a through truss above."""
    origin, u, v = spec.frame(route)
    u0, u1, er, el = spec.extent(route)
    h, d, w = spec.deck_height_m, spec.girder_depth_m, spec.deck_width_m
    length, mid = u1 - u0, 0.5 * (u0 + u1)
    deck_bottom = h + d
    girders_v = np.linspace(-w / 2 + 0.6, w / 2 - 0.6, 5)
    steel = _i_girders(origin, u, v, u0, u1, girders_v, h, d)
    panels = np.arange(u0, u1 + 1e-9, spec.panel_m)
    for k, pu in enumerate(panels[:-1]):
        nu = panels[k + 1]
        for a, b in zip(girders_v[:-1], girders_v[1:]):
            lo, hi = (a, b) if k % 2 == 0 else (b, a)
            steel.append(pipe(_world(origin, u, v, (pu, lo, h + 0.2)), _world(origin, u, v, (nu, hi, h + d - 0.2)), 0.08))
        steel.append(pipe(_world(origin, u, v, (pu, girders_v[0], h + d - 0.3)), _world(origin, u, v, (pu, girders_v[-1], h + d - 0.3)), 0.12))
    for pv in (-w / 4, w / 4):
        steel.append(pipe(_world(origin, u, v, (u0, pv, h + 0.55)), _world(origin, u, v, (u1, pv, h + 0.55)), 0.4, sections=10))
    if spec.truss_height_m > 0:
        z_b, z_t = deck_bottom + spec.deck_thickness_m, deck_bottom + spec.deck_thickness_m + spec.truss_height_m
        for tv in (-w / 2 - 0.3, w / 2 + 0.3):
            steel.append(pipe(_world(origin, u, v, (u0, tv, z_t)), _world(origin, u, v, (u1, tv, z_t)), 0.25, sections=8))
            steel.append(pipe(_world(origin, u, v, (u0, tv, z_b + 0.2)), _world(origin, u, v, (u1, tv, z_b + 0.2)), 0.25, sections=8))
            for k, pu in enumerate(panels):
                steel.append(pipe(_world(origin, u, v, (pu, tv, z_b)), _world(origin, u, v, (pu, tv, z_t)), 0.15))
                if k + 1 < len(panels):
                    a, b = (z_b, z_t) if k % 2 == 0 else (z_t, z_b)
                    steel.append(pipe(_world(origin, u, v, (pu, tv, a)), _world(origin, u, v, (panels[k + 1], tv, b)), 0.12))
    parts = [
        Part(f"{spec.name}_girders", "girder", MATERIALS["steel"], merge(steel)),
        Part(
            f"{spec.name}_deck",
            "bridge_deck",
            MATERIALS["concrete"],
            merge([_local_box(origin, u, v, (mid, 0.0, deck_bottom + spec.deck_thickness_m / 2), (length, w, spec.deck_thickness_m))]),
        ),
    ]
    piers = _piers(spec, route, origin, u, v, h)
    if piers:
        parts.append(Part(f"{spec.name}_piers", "pier", MATERIALS["concrete"], merge(piers)))
    abut = _abutments(spec, origin, u, v, (u0, u1, er, el), h)
    if abut:
        parts.append(Part(f"{spec.name}_abutments", "pier", MATERIALS["concrete"], merge(abut)))
    return parts


BUILDERS = {"beam": build_beam, "arch": build_arch, "truss": build_truss}


def build_bridge(spec: BridgeSpec, route: Route) -> list[Part]:
    """Parts of one bridge of any type."""
    return BUILDERS[spec.type](spec, route)


def shadow(spec: BridgeSpec, route: Route) -> tuple[float, float]:
    """Station range (start, end) of the route under the deck footprint (where GPS is blocked)."""
    origin, u, v = spec.frame(route)
    u0, u1, _, _ = spec.extent(route)
    rel = route.xy - origin
    pu, pv = rel @ u, rel @ v
    under = (np.abs(pv) <= spec.deck_width_m / 2) & (pu >= u0) & (pu <= u1) & (np.abs(route.s - spec.station_m) < 4 * spec.deck_width_m + 50)
    s = route.s[under]
    return (float(s.min()), float(s.max())) if len(s) else (spec.station_m, spec.station_m)


def summary(spec: BridgeSpec, route: Route) -> dict:
    """Json-able record of a placed bridge for world.params['structures']."""
    start, end = shadow(spec, route)
    u0, u1, _, _ = spec.extent(route)
    return {
        "name": spec.name,
        "type": f"{spec.type}_bridge",
        "station_m": spec.station_m,
        "deck_height_m": spec.deck_height_m,
        "deck_width_m": spec.deck_width_m,
        "crossing_angle_deg": spec.crossing_angle_deg,
        "length_m": float(u1 - u0),
        "shadow_start_m": start,
        "shadow_end_m": end,
        "piers": len(spec.piers_u(route)),
        "pier_spacing_m": spec.pier_spacing_m,
    }
