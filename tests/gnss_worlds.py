"""Worlds and motions with known geometry for the GNSS tests: open water, a bridge deck, a canyon."""

from __future__ import annotations

import numpy as np
import trimesh

from worlds.materials import CONCRETE, WATER
from worlds.route import Route
from worlds.world import Part, World

ORIGIN = (42.3539, -71.1106, 0.0)
NOISE_OFF = {"white_zenith_m": 0.0, "correlated_zenith_m": 0.0, "cn0_jitter_db": 0.0}


def box(lo, hi) -> trimesh.Trimesh:
    """Axis-aligned box from corner lo to corner hi (outward normals)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    mesh = trimesh.creation.box(extents=hi - lo)
    mesh.apply_translation((lo + hi) / 2)
    return mesh


def water_part(x0=-200.0, x1=1200.0, half_width=300.0) -> Part:
    return Part("water", "water", WATER, box((x0, -half_width, -1.0), (x1, half_width, 0.0)))


def route(length=1000.0) -> Route:
    return Route.from_waypoints(np.array([[0.0, 0.0], [length, 0.0]]), 40.0, 40.0)


def open_water() -> World:
    return World("open_water", [water_part()], route(), ORIGIN)


DECK = ((100.0, -200.0, 4.0), (160.0, 200.0, 5.0))
"""A 60 m wide bridge deck across the channel, underside 4 m above the water."""


def bridge() -> World:
    return World("bridge", [water_part(), Part("deck", "bridge_deck", CONCRETE, box(*DECK))], route(), ORIGIN)


def canyon(north_y=18.0, south_y=-18.0, height=45.0, x0=0.0, x1=300.0) -> World:
    """Two tall facades along the route between x0 and x1 (faces at y = north_y and y = south_y)."""
    north = Part("north", "building", CONCRETE, box((x0, north_y, -1.0), (x1, north_y + 20.0, height)))
    south = Part("south", "building", CONCRETE, box((x0, south_y - 20.0, -1.0), (x1, south_y, height)))
    return World("canyon", [water_part(), north, south], route(), ORIGIN)


def solid_building() -> World:
    """Open water with one closed building block at x 50..80, y 20..50, 30 m tall."""
    block = Part("block", "building", CONCRETE, box((50.0, 20.0, -1.0), (80.0, 50.0, 30.0)))
    return World("block", [water_part(), block], route(), ORIGIN)


class Straight:
    """Level motion along +x at constant speed and lateral offset y (base_link at the waterline)."""

    def __init__(self, speed=2.0, x0=0.0, y=0.0):
        self.speed, self.x0, self.y = speed, x0, y

    def pose(self, t: float) -> np.ndarray:
        pose = np.eye(4)
        pose[:3, 3] = (self.x0 + self.speed * t, self.y, 0.0)
        return pose


class Static:
    """A vessel that does not move."""

    def __init__(self, x=0.0, y=0.0, z=0.0, yaw_deg=0.0):
        c, s = np.cos(np.deg2rad(yaw_deg)), np.sin(np.deg2rad(yaw_deg))
        self.matrix = np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1]], dtype=float)

    def pose(self, t: float) -> np.ndarray:
        return self.matrix.copy()


def direction(az_deg: float, el_deg: float) -> np.ndarray:
    """Unit ENU vector towards azimuth az (clockwise from north) and elevation el."""
    az, el = np.deg2rad(az_deg), np.deg2rad(el_deg)
    return np.array([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)])


def ray_hits_box(origin, d, lo, hi) -> bool:
    """Slab test: does the ray origin + t d (t > 0) meet the axis-aligned box [lo, hi]?"""
    t0, t1 = 0.0, np.inf
    for k in range(3):
        if abs(d[k]) < 1e-15:
            if not lo[k] <= origin[k] <= hi[k]:
                return False
            continue
        a, b = (lo[k] - origin[k]) / d[k], (hi[k] - origin[k]) / d[k]
        t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
    return t0 <= t1
