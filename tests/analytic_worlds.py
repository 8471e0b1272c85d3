"""Small worlds with known geometry for analytic tests (a wall, a cylinder, open water, ground)."""

from __future__ import annotations

import numpy as np
import trimesh

from worlds.materials import CONCRETE, SOIL, STEEL, WATER
from worlds.route import Route
from worlds.world import Part, World

ORIGIN = (42.3539, -71.1106, 0.0)


def box(extents, centre) -> trimesh.Trimesh:
    mesh = trimesh.creation.box(extents=extents)
    mesh.apply_translation(centre)
    return mesh


def water(length: float = 1200.0, width: float = 400.0) -> Part:
    return Part("water", "water", WATER, box((length, width, 1.0), (length / 2 - 100, 0.0, -0.5)))


def straight_route(length: float = 600.0) -> Route:
    return Route.from_waypoints(np.array([[0.0, 0.0], [length, 0.0]]), 50.0, 50.0)


def wall_world(distance_m: float = 10.0, height_m: float = 6.0, material=CONCRETE) -> World:
    """Water and one long wall whose face is the plane y = distance_m (left of a route along +x)."""
    wall = box((1200.0, 1.0, height_m + 2.0), (500.0, distance_m + 0.5, height_m / 2 - 1.0))
    return World("wall", [water(), Part("wall", "wall", material, wall)], straight_route(), ORIGIN)


def cylinder_world(radius_m: float = 1.0, centre=(40.0, 8.0)) -> World:
    """Water and one vertical steel cylinder (a pier) of known radius and axis."""
    cyl = trimesh.creation.cylinder(radius=radius_m, height=12.0, sections=256)
    cyl.apply_translation((centre[0], centre[1], 4.0))
    return World("cylinder", [water(), Part("pier", "pier", STEEL, cyl)], straight_route(), ORIGIN)


def front_wall_world(x_m: float = 40.0) -> World:
    """Water and a wall across the route: its face is the plane x = x_m, ahead of the vessel."""
    wall = box((1.0, 200.0, 10.0), (x_m + 0.5, 0.0, 3.0))
    return World("front_wall", [water(), Part("wall", "wall", CONCRETE, wall)], straight_route(30.0), ORIGIN)


def ground_world() -> World:
    """Dry ground (soil) level with the waterline everywhere: every downward ray returns."""
    ground = box((1200.0, 400.0, 1.0), (500.0, 0.0, -0.5))
    return World("ground", [Part("ground", "bank", SOIL, ground)], straight_route(), ORIGIN)


def open_water_world() -> World:
    return World("open_water", [water()], straight_route(), ORIGIN)
