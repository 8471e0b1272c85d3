"""Traffic: the other vessels on the river (a chase boat, crossing, overtaking and oncoming boats).

`Traffic` holds the movers and answers what the sensors and the truth need: `poses(ts)` of every
mover, the distance along world rays to the nearest mover at a time (GNSS line of sight), and GNSS
reflections off steel hulls. `TrafficConfig` is the `[traffic]` section of a scenario file, built
into a Traffic over a world and the ASV's trajectory by `build_traffic`.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Annotated, Literal

import numpy as np
import numpy.typing as npt
from pydantic import BaseModel, ConfigDict, Field, model_validator

from sim.boats import BoatKind, boat
from sim.movers import AlongRoute, Chase, Crossing, Motion, Mover, rigid_inverse
from sim.multipath import Reflections

LANDING_MARGIN_M = 5.0
"""A crossing boat waits this far (plus its half length) inside the bank."""


@dataclass(frozen=True)
class Traffic:
    """The movers of a run, in a fixed order: LiDAR label len(world.parts) + i is mover i."""

    movers: tuple[Mover, ...] = ()

    def __bool__(self) -> bool:
        return bool(self.movers)

    def __len__(self) -> int:
        return len(self.movers)

    @property
    def ids(self) -> list[str]:
        return [m.id for m in self.movers]

    @property
    def reflectivity(self) -> np.ndarray:
        """905 nm reflectivity per mover (float32)."""
        return np.array([m.material.reflectivity for m in self.movers], dtype=np.float32)

    def poses(self, ts: npt.ArrayLike) -> np.ndarray:
        """(M, N, 4, 4) world<-body of every mover at times ts (N,)."""
        ts = np.atleast_1d(np.asarray(ts, dtype=float))
        return np.stack([m.poses(ts) for m in self.movers]) if self.movers else np.zeros((0, len(ts), 4, 4))

    def distance(self, rays: np.ndarray, t: float) -> np.ndarray:
        """(N,) distance along world rays (origin, unit direction) to the nearest mover at time t; inf where none."""
        out = np.full(len(rays), np.inf)
        origins, directions = rays[:, :3].astype(float), rays[:, 3:].astype(float)
        for mover, pose in zip(self.movers, self.poses([t])[:, 0]):
            centre, radius = mover.sphere
            v = pose[:3, :3] @ centre + pose[:3, 3] - origins
            along = np.einsum("ij,ij->i", v, directions)
            near = np.flatnonzero((np.einsum("ij,ij->i", v, v) - along**2 <= radius**2) & (along >= -radius))
            if len(near):
                inv = rigid_inverse(pose[None])[0]
                t_hit, _ = mover.cast(origins[near] @ inv[:3, :3].T + inv[:3, 3], directions[near] @ inv[:3, :3].T)
                out[near] = np.minimum(out[near], t_hit)
        return out

    def reflections(self, antenna: np.ndarray, directions: np.ndarray, t: float, radius_m: float) -> Reflections:
        """GNSS reflections off the movers' hull and cabin sides at time t (world frame), for satellite `directions`
        (at least one mover)."""
        found = [m.reflections(pose, antenna, directions, radius_m) for m, pose in zip(self.movers, self.poses([t])[:, 0])]
        return functools.reduce(Reflections.joined, found[1:], found[0])


class _MoverConfig(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    id: str | None = Field(None, pattern=r"^[A-Za-z_][A-Za-z0-9_]*$", description="name in movers.csv (default: kind and index, e.g. 'crossing_1')")
    boat: BoatKind = Field("cruiser", description="boat kind: runabout (5.5 m), cruiser (10 m), barge (30 m, 7.5 m wheelhouse)")


class ChaseConfig(_MoverConfig):
    """A chase boat following the ASV at a set distance and lateral offset (the field study's ASV was driven from one)."""

    kind: Literal["chase"] = Field("chase", description="mover kind: chase, crossing or along")
    boat: BoatKind = Field("runabout", description="boat kind: runabout (5.5 m), cruiser (10 m), barge (30 m, 7.5 m wheelhouse)")
    distance_m: float = Field(15.0, gt=0, description="centre behind the ASV's base_link, along its heading, m")
    lateral_m: float = Field(-6.0, description="centre to the ASV's left, m (negative: to its right)")
    lag_s: float = Field(0.0, ge=0, le=60, description="follow the ASV's pose this long ago, s (> 0: in its wake)")


class CrossingConfig(_MoverConfig):
    """A boat crossing the river straight across the route at a chosen station and time, waiting at its landings."""

    kind: Literal["crossing"] = Field("crossing", description="mover kind: chase, crossing or along")
    station_m: float = Field(..., ge=0, description="route station where it crosses the centreline, m")
    time_s: float = Field(..., ge=0, description="scenario time at which it crosses the centreline, s")
    speed_mps: float = Field(3.0, gt=0, le=15, description="speed over ground, m/s")
    angle_deg: float = Field(
        90.0,
        ge=-150,
        le=150,
        description="heading from the route's direction, deg (90: from the right bank to the left; -90: the other way; |angle| >= 30)",
    )

    @model_validator(mode="after")
    def _across(self) -> CrossingConfig:
        if abs(self.angle_deg) < 30:
            raise ValueError(f"angle_deg ({self.angle_deg}) must be at least 30 deg off the route's direction")
        return self


class AlongConfig(_MoverConfig):
    """A boat along the route at constant speed: overtaking (faster than the ASV, same way) or oncoming."""

    kind: Literal["along"] = Field("along", description="mover kind: chase, crossing or along")
    station_m: float = Field(..., ge=0, description="route station where it is at time_s, m")
    time_s: float = Field(..., ge=0, description="scenario time at which it is at station_m, s")
    speed_mps: float = Field(4.0, gt=0, le=15, description="speed over ground, m/s")
    oncoming: bool = Field(False, description="true: travels down the route towards the ASV")
    lateral_m: float = Field(15.0, description="offset to the left of the route's centreline, m (negative: right)")


MoverConfig = Annotated[ChaseConfig | CrossingConfig | AlongConfig, Field(discriminator="kind")]


class TrafficConfig(BaseModel):
    """Other vessels on the river, each a rigid boat on its own trajectory (`kind`: chase, crossing or along)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    movers: list[MoverConfig] = Field(default_factory=list, description="the boats; none: a static world")

    @model_validator(mode="after")
    def _ids(self) -> TrafficConfig:
        named = [m if m.id else m.model_copy(update={"id": f"{m.kind}_{i}"}) for i, m in enumerate(self.movers)]
        ids = [m.id for m in named]
        for i in ids:
            if ids.count(i) > 1:
                raise ValueError(f"movers: id {i!r} is used twice")
        object.__setattr__(self, "movers", named)
        return self


def build_traffic(config: TrafficConfig | None, world, trajectory, t_start: float = 0.0) -> Traffic:
    """The movers of `config` over `world` (its route) and the ASV's `trajectory` (what a chase boat follows, known
    from `t_start` on)."""
    movers = []
    for spec in config.movers if config is not None else ():
        mesh, material = boat(spec.boat)
        motion: Motion
        if spec.kind == "chase":
            motion = Chase(trajectory, spec.distance_m, spec.lateral_m, spec.lag_s, t_start)
        elif spec.kind == "crossing":
            margin = float(mesh.bounds[1, 0] - mesh.bounds[0, 0]) / 2 + LANDING_MARGIN_M
            motion = Crossing.across(world.route, spec.station_m, spec.time_s, spec.speed_mps, spec.angle_deg, margin)
        else:
            motion = AlongRoute(world.route, spec.station_m, spec.time_s, spec.speed_mps, spec.lateral_m, spec.oncoming)
        assert spec.id is not None  # TrafficConfig names every mover
        movers.append(Mover(spec.id, mesh, material, motion))
    return Traffic(tuple(movers))
