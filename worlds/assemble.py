"""Put a world together from a route, a channel, bridges, locks and building rows."""

from __future__ import annotations

import dataclasses

import numpy as np

from worlds.bridges import BridgeSpec, build_bridge
from worlds.bridges import summary as bridge_summary
from worlds.buildings import BuildingRow, build_buildings
from worlds.channel import Centerline, ChannelParams, build_channel, edge_summary
from worlds.crowns import Crowns
from worlds.lock import LockSpec, build_lock
from worlds.lock import summary as lock_summary
from worlds.riverside import Riverside, build_riverside
from worlds.route import Route
from worlds.world import World

BOSTON_BU_BRIDGE = (42.3539, -71.1106, 0.0)


def assemble(
    name: str,
    route: Route,
    channel: ChannelParams,
    bridges: list[BridgeSpec],
    locks: list[LockSpec],
    rows: list[BuildingRow],
    seed: int,
    origin: tuple[float, float, float],
    params: dict,
    riverside: Riverside | None = None,
) -> World:
    """Build every part; params gets 'structures' (bridges and locks sorted by station), 'edges'
    (wall/quay/bank stretches per side), 'building_rows' and 'riverside' (trees, docks, mooring
    fields) added, all with route stations. The riverside goes in last, around everything else.

    Inside a lock chamber the route's bank distances become the chamber walls' distances.
    """
    names = [b.name for b in bridges] + [lk.name for lk in locks]
    if len(set(names)) != len(names):
        raise ValueError(f"{name}: structure names must be unique, got {names}")
    parts = build_channel(route, channel)
    for spec in bridges:
        parts += build_bridge(spec, route)
    for lock in locks:
        parts += build_lock(lock, route)
    keep_clear = [(b.station_m - b.deck_width_m, b.station_m + b.deck_width_m) for b in bridges]
    keep_clear += [(lk.station_m - lk.length_m / 2 - 10, lk.station_m + lk.length_m / 2 + 10) for lk in locks]
    line = Centerline.of(route, channel.end_extension_m)
    parts += build_buildings(rows, line, seed, keep_clear)
    living, crowns, living_summary = build_riverside(riverside, route, line, channel, parts, seed) if riverside else ([], Crowns.empty(), {})
    parts += living
    structures = [bridge_summary(b, route) for b in bridges] + [lock_summary(lk) for lk in locks]
    params = {
        **params,
        "structures": sorted(structures, key=lambda d: d["station_m"]),
        "edges": edge_summary(route, channel),
        "building_rows": [row.model_dump(mode="json") for row in rows],
        "riverside": living_summary,
        "route_length_m": route.length,
    }
    return World(name=name, parts=parts, route=_narrow_in_locks(route, locks), origin=origin, params=params, crowns=crowns)


def _narrow_in_locks(route: Route, locks: list[LockSpec]) -> Route:
    """Route whose bank distances inside each lock chamber are the chamber walls'."""
    left, right = route.left_m.copy(), route.right_m.copy()
    for lock in locks:
        a, b = lock.stations()
        inside = (route.s >= a) & (route.s <= b)
        left[inside] = np.minimum(left[inside], lock.chamber_width_m / 2)
        right[inside] = np.minimum(right[inside], lock.chamber_width_m / 2)
    return dataclasses.replace(route, left_m=left, right_m=right)
