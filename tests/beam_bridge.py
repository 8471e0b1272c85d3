"""A straight open river under one beam bridge (deck 6 m up, 20 m wide, piers 40 m apart, girders 3 m apart): the world
the gicp screens' tests (co-moving and boats under way) pass under, where the piers alone hold the motion along the route."""

from __future__ import annotations

import worlds
from worlds.bridges import BridgeSpec


def beam_bridge_river(station_m: float) -> worlds.World:
    """The river with its beam bridge at route station `station_m`."""
    bridge = BridgeSpec(
        name="bridge", type="beam", station_m=station_m, deck_height_m=6.0, deck_width_m=20.0, pier_spacing_m=40.0, girder_spacing_m=3.0
    )
    return worlds.load("open_river", length_m=400.0, width_m=120.0, bend_amplitude_m=0.0, bridges=[bridge])
