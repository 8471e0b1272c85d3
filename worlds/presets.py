"""The preset worlds: charles_river, canal_lock, open_river. Each is a pydantic parameter model plus a builder.

Keyword overrides go through the model (unknown keys and bad values -> ValueError naming the key);
`World.params` holds the resolved parameters (json-able) plus the placed structures.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from worlds.assemble import BOSTON_BU_BRIDGE, assemble
from worlds.bridges import BridgeSpec
from worlds.buildings import BuildingRow
from worlds.channel import ChannelParams, EdgeStretch, EdgeStyle
from worlds.lock import LockSpec
from worlds.moorings import Dock, MooringField
from worlds.params import validate
from worlds.riverside import Riverside, RiversideParams
from worlds.route import Route
from worlds.vegetation import TreeRow
from worlds.world import World


class PresetParams(BaseModel):
    """Parameters every preset accepts."""

    model_config = ConfigDict(extra="forbid")

    seed: int = Field(0, ge=0, description="seed of the random building layout (riverbench.rng stream 'worlds.buildings')")
    origin: tuple[float, float, float] = Field(BOSTON_BU_BRIDGE, description="geodetic origin (lat deg, lon deg, alt m) of the ENU frame")
    bridges: list[BridgeSpec] | None = Field(None, description="replace the preset's bridges with these (None = the preset's own)")
    buildings: bool = Field(True, description="place the preset's city blocks")


# --------------------------------------------------------------------------------------------- #
# charles_river


CHARLES_WAYPOINTS = np.array(
    [
        # ENU (east, north) m from the BU Bridge; the vessel's path, ~60 m off the Esplanade wall in the basin
        [-120.0, -40.0],
        [0.0, 0.0],
        [350.0, 70.0],
        [800.0, 140.0],
        [1570.0, 200.0],
        [2250.0, 430.0],
        [2900.0, 830.0],
        [3100.0, 1180.0],
        [3260.0, 1540.0],
        [3600.0, 1640.0],
        [3950.0, 1640.0],
        [4100.0, 1780.0],
        [4160.0, 1880.0],
    ]
)
CHARLES_RIVER_WIDTH = np.array([200.0, 200.0, 280.0, 450.0, 580.0, 520.0, 450.0, 220.0, 130.0, 150.0, 150.0, 200.0, 240.0])
CHARLES_BASIN = (1, 7)  # waypoints between which the route keeps `esplanade_offset_m` off the right bank


class CharlesRiverParams(PresetParams, RiversideParams):
    """The Charles River from the BU Bridge to the Charlestown Bridge (see worlds/charles_river.md)."""

    esplanade_offset_m: float = Field(60.0, ge=20.0, le=150.0, description="route distance from the Esplanade sea wall (right bank) in the basin, m")
    building_height_scale: float = Field(1.0, gt=0.0, le=3.0, description="multiplies every building height range")
    lock_gate_type: Literal["mitre", "lift"] = Field("mitre", description="gate type of the Charles River Dam lock")


def _charles_route(p: CharlesRiverParams) -> Route:
    right = CHARLES_RIVER_WIDTH / 2
    a, b = CHARLES_BASIN
    right[a + 1 : b + 1] = np.minimum(p.esplanade_offset_m, right[a + 1 : b + 1])
    right[a] = min(right[a], 100.0)
    return Route.from_waypoints(CHARLES_WAYPOINTS, CHARLES_RIVER_WIDTH - right, right, spacing_m=1.0)


def _charles_bridges(route: Route) -> list[BridgeSpec]:
    at = route.station_of
    return [
        BridgeSpec(
            name="bu_bridge",
            type="truss",
            station_m=at((0.0, 0.0)),
            crossing_angle_deg=12.0,
            deck_height_m=8.0,
            deck_width_m=20.0,
            pier_spacing_m=60.0,
            pier_width_m=3.0,
            truss_height_m=6.0,
        ),
        BridgeSpec(
            name="harvard_bridge",
            type="beam",
            station_m=at((1570.0, 200.0)),
            crossing_angle_deg=-5.0,
            deck_height_m=7.0,
            deck_width_m=21.0,
            pier_spacing_m=27.5,
            pier_width_m=2.5,
            girder_spacing_m=3.0,
            girder_depth_m=1.5,
        ),
        BridgeSpec(
            name="longfellow_bridge",
            type="arch",
            station_m=at((2900.0, 830.0)),
            deck_height_m=8.5,
            deck_width_m=32.0,
            pier_spacing_m=52.0,
            pier_width_m=6.0,
            arch_spring_m=2.5,
            parapet_m=1.3,
            rib_spacing_m=4.5,
            rib_depth_m=1.5,
            panel_m=4.0,
        ),
        BridgeSpec(
            name="museum_dam_bridge",
            type="beam",
            station_m=at((3260.0, 1540.0)),
            deck_height_m=5.0,
            deck_width_m=30.0,
            pier_spacing_m=22.0,
            pier_width_m=2.0,
            girder_spacing_m=3.0,
            girder_depth_m=1.2,
        ),
        BridgeSpec(
            name="charlestown_bridge",
            type="beam",
            station_m=at((4100.0, 1780.0)),
            crossing_angle_deg=10.0,
            deck_height_m=6.0,
            deck_width_m=30.0,
            pier_spacing_m=40.0,
            pier_width_m=3.0,
            girder_spacing_m=3.0,
            girder_depth_m=2.0,
        ),
    ]


def _charles_channel(route: Route) -> ChannelParams:
    at = route.station_of
    lower = at((3000.0, 1000.0))  # downstream of the Longfellow Bridge: quays instead of sea walls
    sea_wall = EdgeStyle(type="wall", material="granite", top_m=2.5, ground_width_m=170.0)
    quay = dict(type="quay", material="granite", top_m=3.0, quay_deck_m=10.0, ground_width_m=150.0)
    bank = dict(type="bank", slope=0.3, top_m=3.0, ground_width_m=170.0)
    return ChannelParams(
        left=sea_wall,
        right=sea_wall,
        end_extension_m=200.0,
        stretches=[
            EdgeStretch(side="left", start_m=-1e6, end_m=at((350.0, 70.0)), **bank),
            EdgeStretch(side="right", start_m=-1e6, end_m=-20.0, **bank),
            EdgeStretch(side="left", start_m=lower, end_m=1e6, **quay),
            EdgeStretch(side="right", start_m=lower, end_m=1e6, **quay),
        ],
    )


def _charles_buildings(route: Route, scale: float) -> list[BuildingRow]:
    at = route.station_of
    h = lambda lo, hi: (lo * scale, hi * scale)
    return [
        # Back Bay brownstones behind the Esplanade and Storrow Drive
        BuildingRow(
            side="right",
            start_m=at((400.0, 70.0)),
            end_m=at((2700.0, 700.0)),
            setback_m=70.0,
            ground_m=2.5,
            height_m=h(15.0, 35.0),
            frontage_m=(20.0, 45.0),
            depth_m=(15.0, 30.0),
            rows=2,
        ),
        # Beacon Hill, the West End and North Station: tall, close to the river
        BuildingRow(
            side="right",
            start_m=at((2950.0, 900.0)),
            end_m=route.length + 150.0,
            setback_m=30.0,
            ground_m=3.0,
            height_m=h(20.0, 100.0),
            frontage_m=(25.0, 50.0),
            depth_m=(20.0, 35.0),
            rows=2,
        ),
        # MIT and Kendall Square behind Memorial Drive
        BuildingRow(
            side="left",
            start_m=at((800.0, 140.0)),
            end_m=at((2900.0, 830.0)),
            setback_m=45.0,
            ground_m=2.5,
            height_m=h(15.0, 60.0),
            frontage_m=(30.0, 60.0),
            depth_m=(20.0, 40.0),
        ),
        # East Cambridge and Charlestown
        BuildingRow(
            side="left",
            start_m=at((3100.0, 1180.0)),
            end_m=route.length + 150.0,
            setback_m=25.0,
            ground_m=3.0,
            height_m=h(10.0, 45.0),
            frontage_m=(20.0, 45.0),
            depth_m=(15.0, 30.0),
        ),
    ]


def _charles_riverside(route: Route, p: CharlesRiverParams) -> Riverside:
    """The Esplanade and Memorial Drive tree lines, parks on the lower river, the sailing clubs' docks
    and moorings, and the dam lock's waiting pontoons (see worlds/charles_river.md)."""
    at = route.station_of
    longfellow = at((2900.0, 830.0))
    lower, dam = longfellow + 40.0, at((3950.0, 1640.0))
    big = dict(height_m=(14.0, 24.0), crown_radius_m=(4.0, 7.0))
    park = dict(setback_m=(4.0, 12.0), spacing_m=(8.0, 14.0), height_m=(12.0, 20.0), crown_radius_m=(3.5, 6.0))
    trees = [
        TreeRow(
            side="right", start_m=0.0, end_m=longfellow - 40.0, setback_m=(3.0, 7.0), spacing_m=(8.0, 13.0), crown_base=(0.1, 0.3), **big
        ),  # the Esplanade: planes, lindens and willows along the wall
        TreeRow(
            side="right",
            start_m=0.0,
            end_m=longfellow - 40.0,
            setback_m=(12.0, 55.0),
            spacing_m=(12.0, 22.0),
            height_m=(12.0, 22.0),
            crown_radius_m=(3.5, 6.5),
        ),  # its park behind
        TreeRow(
            side="left",
            start_m=-150.0,
            end_m=at((350.0, 70.0)),
            setback_m=(12.0, 45.0),
            spacing_m=(10.0, 18.0),
            height_m=(10.0, 20.0),
            crown_radius_m=(3.5, 6.0),
        ),  # Magazine Beach
        TreeRow(
            side="left", start_m=at((350.0, 70.0)), end_m=longfellow - 40.0, setback_m=(3.0, 10.0), spacing_m=(9.0, 14.0), **big
        ),  # Memorial Drive
        TreeRow(side="right", start_m=lower, end_m=dam - 60.0, **park),  # Charlesbank, Nashua Street
        TreeRow(side="left", start_m=lower, end_m=dam - 60.0, **park),  # Lechmere, North Point Park
        TreeRow(
            side="left",
            start_m=dam + 60.0,
            end_m=route.length + 150.0,
            setback_m=(5.0, 20.0),
            spacing_m=(12.0, 20.0),
            height_m=(8.0, 14.0),
            crown_radius_m=(3.0, 5.0),
        ),  # Paul Revere Park
    ]
    dinghies = dict(boat_length_m=(4.0, 6.0), sail_share=1.0)
    keelboats = dict(boat_length_m=(7.0, 11.0), sail_share=0.7)
    docks = [
        Dock(name="bu_sailing_pavilion", side="right", station_m=at((800.0, 140.0)) - 250.0, length_m=35.0, boats=10, **dinghies),
        Dock(name="harvard_sailing_center", side="left", station_m=at((1570.0, 200.0)) + 140.0, length_m=30.0, boats=8, **dinghies),
        Dock(name="mit_sailing_pavilion", side="left", station_m=at((1570.0, 200.0)) + 240.0, length_m=40.0, boats=14, **dinghies),
        Dock(
            name="esplanade_lagoon",
            side="right",
            station_m=at((2250.0, 430.0)) + 220.0,
            type="pier",
            orientation="along",
            length_m=40.0,
            boats=3,
            boat_length_m=(6.0, 10.0),
            sail_share=0.2,
        ),
        *[
            Dock(
                name=f"community_boating_{k}",
                side="right",
                station_m=longfellow - d,
                length_m=32.0,
                boats=12,
                boat_length_m=(4.5, 7.0),
                sail_share=0.9,
            )
            for k, d in enumerate((150.0, 125.0, 100.0))
        ],
        Dock(name="charles_river_yacht_club", side="left", station_m=longfellow - 150.0, length_m=40.0, boats=10, **keelboats),
        Dock(
            name="museum_of_science_landing",
            side="left",
            station_m=at((3260.0, 1540.0)) + 100.0,
            orientation="along",
            length_m=25.0,
            boats=2,
            boat_length_m=(8.0, 12.0),
            sail_share=0.0,
        ),
        Dock(
            name="dam_lock_waiting_upstream",
            side="right",
            station_m=dam - 120.0,
            orientation="along",
            length_m=40.0,
            width_m=3.0,
            boats=3,
            boat_length_m=(8.0, 12.0),
            sail_share=0.3,
        ),
        Dock(
            name="dam_lock_waiting_downstream",
            side="left",
            station_m=dam + 80.0,
            orientation="along",
            length_m=30.0,
            width_m=3.0,
            boats=2,
            boat_length_m=(8.0, 12.0),
            sail_share=0.3,
        ),
    ]
    fields = [
        MooringField(
            name="community_boating_moorings",
            side="right",
            start_m=longfellow - 250.0,
            end_m=longfellow - 60.0,
            offset_m=(36.0, 44.0),
            spacing_m=12.0,
            boat_length_m=(4.5, 7.0),
            sail_share=0.9,
        ),
        MooringField(
            name="charles_river_yacht_club_moorings",
            side="left",
            start_m=longfellow - 350.0,
            end_m=longfellow - 60.0,
            offset_m=(50.0, 150.0),
            spacing_m=22.0,
            **keelboats,
        ),
    ]
    return Riverside(RiversideParams(**p.model_dump(include=set(RiversideParams.model_fields))), trees, docks, fields)


def charles_river(p: CharlesRiverParams) -> World:
    """Charles River, BU Bridge to Charlestown Bridge: five bridges, the dam lock, sea walls, downtown blocks.

    Approximate real geometry and distances; worlds/charles_river.md says what is approximate.
    """
    route = _charles_route(p)
    bridges = p.bridges if p.bridges is not None else _charles_bridges(route)
    lock = LockSpec(
        name="charles_river_dam_lock",
        station_m=route.station_of((3950.0, 1640.0)),
        length_m=80.0,
        chamber_width_m=14.0,
        top_m=4.0,
        gate_type=p.lock_gate_type,
        road_width_m=20.0,
        road_height_m=6.5,
    )
    rows = _charles_buildings(route, p.building_height_scale) if p.buildings else []
    at = route.station_of
    stretches = [
        ("bu_reach", 0.0, at((350.0, 70.0))),
        ("esplanade_basin", at((350.0, 70.0)), at((2900.0, 830.0))),
        ("lower_river", at((2900.0, 830.0)), at((3950.0, 1640.0)) - 60.0),
        ("dam_and_harbour", at((3950.0, 1640.0)) - 60.0, route.length),
    ]
    params = p.model_dump(mode="json") | {"stretches": [{"name": n, "start_m": a, "end_m": b} for n, a, b in stretches]}
    return assemble("charles_river", route, _charles_channel(route), bridges, [lock], rows, p.seed, p.origin, params, _charles_riverside(route, p))


# --------------------------------------------------------------------------------------------- #
# canal_lock


CANAL_WAYPOINTS = np.array(
    # collinear every 50 m up to 450 m so the spline is straight (< 0.1 deg) over CANAL_STRAIGHT
    [[x, 0.0] for x in range(0, 451, 50)] + [[560.0, 25.0], [660.0, 75.0], [760.0, 105.0], [880.0, 115.0], [1000.0, 115.0]],
    dtype=float,
)
CANAL_STRAIGHT = (20.0, 300.0)


class CanalLockParams(PresetParams, RiversideParams):
    """A short urban canal with vertical walls, two low bridges, a lock and buildings."""

    width_m: float = Field(26.0, ge=14.0, le=60.0, description="canal width between the walls, m (route in the middle)")
    wall_height_m: float = Field(3.0, gt=0.5, le=10.0, description="wall top above the water, m")
    bridge_deck_height_m: float = Field(3.5, gt=1.0, le=20.0, description="clearance of both bridges above the water, m")
    bridge_width_m: float = Field(12.0, gt=0.0, le=60.0, description="deck width of both bridges, m")
    lock_chamber_width_m: float = Field(12.0, gt=4.0, le=50.0, description="lock chamber width, m")
    lock_length_m: float = Field(70.0, gt=40.0, le=150.0, description="lock chamber length, m")
    lock_gate_type: Literal["mitre", "lift"] = Field("mitre", description="lock gate type")


def canal_lock(p: CanalLockParams) -> World:
    """Walled canal: a straight featureless stretch, a beam bridge, a lock, a steel footbridge, buildings."""
    route = Route.from_waypoints(CANAL_WAYPOINTS, p.width_m / 2, p.width_m / 2)
    wall = EdgeStyle(type="wall", top_m=p.wall_height_m, ground_width_m=70.0)
    channel = ChannelParams(left=wall, right=wall, end_extension_m=100.0)
    bridges = (
        p.bridges
        if p.bridges is not None
        else [
            BridgeSpec(
                name="road_bridge",
                type="beam",
                station_m=400.0,
                deck_height_m=p.bridge_deck_height_m,
                deck_width_m=p.bridge_width_m,
                pier_spacing_m=100.0,
                deck_thickness_m=0.8,
                abutment_m=8.0,
            ),
            BridgeSpec(
                name="footbridge",
                type="truss",
                station_m=900.0,
                crossing_angle_deg=10.0,
                deck_height_m=p.bridge_deck_height_m,
                deck_width_m=p.bridge_width_m,
                pier_spacing_m=100.0,
                truss_height_m=3.0,
                girder_depth_m=0.8,
                deck_thickness_m=0.3,
                panel_m=3.0,
                abutment_m=6.0,
            ),
        ]
    )
    lock = LockSpec(
        name="lock",
        station_m=650.0,
        length_m=p.lock_length_m,
        chamber_width_m=p.lock_chamber_width_m,
        top_m=p.wall_height_m + 0.5,
        gate_type=p.lock_gate_type,
        road_width_m=10.0,
        road_height_m=p.wall_height_m + 2.0,
    )
    ground = p.wall_height_m
    rows = (
        [
            BuildingRow(
                side=side,
                start_m=CANAL_STRAIGHT[1] + 30.0,
                end_m=route.length + 100.0,
                setback_m=8.0,
                ground_m=ground,
                height_m=(12.0, 35.0),
                frontage_m=(12.0, 30.0),
                depth_m=(12.0, 20.0),
                gap_m=(0.0, 8.0),
                rows=2,
            )
            for side in ("left", "right")
        ]
        if p.buildings
        else []
    )
    town = CANAL_STRAIGHT[1] + 30.0
    stretches = [{"name": "straight", "start_m": 0.0, "end_m": town}, {"name": "town", "start_m": town, "end_m": route.length}]
    params = p.model_dump(mode="json") | {"straight_stretch_m": list(CANAL_STRAIGHT), "stretches": stretches}
    return assemble("canal_lock", route, channel, bridges, [lock], rows, p.seed, p.origin, params, _canal_riverside(route, p, town))


def _canal_riverside(route: Route, p: CanalLockParams, town: float) -> Riverside:
    """Street trees on both quays in the town (the straight stretch stays bare), a line of boats moored
    along the left wall above the lock and a narrow pontoon with two boats below it."""
    street = dict(setback_m=(1.5, 3.5), spacing_m=(10.0, 16.0), height_m=(7.0, 11.0), crown_radius_m=(1.8, 3.0))
    trees = [TreeRow(side=side, start_m=town, end_m=route.length + 100.0, **street) for side in ("left", "right")]
    docks = [
        Dock(
            name="town_pontoon",
            side="right",
            station_m=760.0,
            orientation="along",
            length_m=24.0,
            width_m=1.2,
            boats=2,
            boat_length_m=(5.0, 7.0),
            sail_share=0.0,
        )
    ]
    fields = [
        MooringField(
            name="quay_moorings",
            side="left",
            start_m=440.0,
            end_m=595.0,
            offset_m=(0.3, 0.3),
            spacing_m=12.0,
            jitter_deg=0.0,
            boat_length_m=(7.0, 10.0),
            sail_share=0.2,
        )
    ]
    return Riverside(RiversideParams(**p.model_dump(include=set(RiversideParams.model_fields))), trees, docks, fields)


# --------------------------------------------------------------------------------------------- #
# open_river


class OpenRiverParams(PresetParams):
    """Wide water between distant natural banks, gentle bends, no structures (the control case)."""

    width_m: float = Field(350.0, ge=100.0, le=2000.0, description="river width between the waterlines, m")
    length_m: float = Field(2000.0, ge=300.0, le=20000.0, description="approximate route length, m")
    right_m: float | None = Field(None, gt=0.0, description="route distance from the right bank, m (None = mid-river)")
    bend_amplitude_m: float = Field(60.0, ge=0.0, le=1000.0, description="lateral amplitude of the gentle bends, m")


def open_river(p: OpenRiverParams) -> World:
    """A wide river with sloped grass banks far from the route."""
    right = p.width_m / 2 if p.right_m is None else p.right_m
    if right >= p.width_m - 1.0:
        raise ValueError(f"open_river: right_m={p.right_m} must be less than width_m={p.width_m}")
    x = np.linspace(0.0, p.length_m, max(int(p.length_m / 200.0), 2) + 1)
    route = Route.from_waypoints(np.c_[x, p.bend_amplitude_m * np.sin(2 * np.pi * x / 1600.0)], p.width_m - right, right)
    bank = EdgeStyle(type="bank", slope=0.2, top_m=4.0, ground_width_m=100.0)
    channel = ChannelParams(left=bank, right=bank, end_extension_m=300.0)
    bridges = p.bridges or []
    return assemble("open_river", route, channel, bridges, [], [], p.seed, p.origin, p.model_dump(mode="json"))


PRESETS: dict[str, tuple[type[PresetParams], Callable[..., World]]] = {
    "canal_lock": (CanalLockParams, canal_lock),
    "charles_river": (CharlesRiverParams, charles_river),
    "open_river": (OpenRiverParams, open_river),
}


def resolve(name: str, overrides: dict) -> PresetParams:
    """The preset's parameter model filled from `overrides` (ValueError naming a bad key)."""
    if name not in PRESETS:
        raise ValueError(f"unknown world {name!r}; available: {', '.join(sorted(PRESETS))}")
    return validate(PRESETS[name][0], overrides, name)


def build(name: str, params: PresetParams) -> World:
    """Build preset `name` from resolved parameters."""
    return PRESETS[name][1](params)
