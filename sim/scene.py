"""Scene: the static world plus the traffic on it, what `HDL32E.scan` and `GnssReceiver.fix` take in place of a World.

The sensors' signatures stay `scan(world, trajectory, t0)` and `fix(world, trajectory, t)`: a plain
World is a static scene, a Scene adds moving boats. sim stays independent of scenarios.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from sim.traffic import Traffic
from worlds.world import World


@dataclass(frozen=True)
class Scene:
    """A World and the Traffic moving on it (LiDAR labels >= len(world.parts) are movers)."""

    world: World
    traffic: Traffic = field(default_factory=Traffic)

    @property
    def route(self):
        """The world's route (what an autopilot follows)."""
        return self.world.route


def split(world: World | Scene) -> tuple[World, Traffic]:
    """(static world, traffic) of what a sensor was given; a plain World has no traffic."""
    if isinstance(world, Scene):
        return world.world, world.traffic
    return world, Traffic()
