"""Monitor 'shadow': distrust a fix that uses a satellite whose line of sight the LiDAR sees blocked (NLOS by shadow
matching on the vessel's own scans, fusion.obstacles).

A used satellite behind a quay, wall or building that the scans show standing above its line of sight reaches the
antenna only by reflection, and its pseudorange carries the extra path. C/N0 says the same only statistically: direct
signals fade too (the water's reflection at low elevation, foliage, the superstructure) and NLOS ones can arrive strong,
so in open water the C/N0 test refuses fixes the environment left within a metre. The map says where a satellite can
be direct and where it cannot, at the satellite's azimuth and elevation the receiver reports (NMEA GSV) and the
satellites it used (GSA). The receiver's filter carries an NLOS epoch's error into the fixes after it, so a blockage is
held for `hold_s` as the C/N0 test holds its deficit.

The monitor builds its map from the scans its host estimator passes it (Monitor.add_scan) with the host's pose, and
forgets it when the host re-locks (that pose was astray). Until the map has seen anything it judges nothing, and a
satellite in a direction the LiDAR never reached is not counted: the map confirms a blockage, it never invents one.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from fusion.monitors.base import FixContext, Monitor
from fusion.observation import FixObservation
from fusion.obstacles import ObstacleMap, ObstacleMapParams
from fusion.verdict import Verdict


class ShadowParams(BaseModel):
    """Parameters of the 'shadow' monitor: its LiDAR height map and how long a blockage is held."""

    model_config = ConfigDict(extra="forbid")

    map: ObstacleMapParams = Field(default_factory=ObstacleMapParams, description="the LiDAR height map (fusion.obstacles)")
    hold_s: float = Field(
        6.0,
        ge=0,
        description="a used satellite seen blocked is held against the fixes this long, s [6: as cn0's hold_s, a consumer "
        "receiver's filter halves a raw fault's effect on its output in about 4 s; 0 = no hold]",
    )


class ShadowMonitor(Monitor):
    """Distrusts a fix that uses (or used within hold_s) a satellite the LiDAR map shows blocked; statistic: how many it uses now."""

    name = "shadow"
    wants_scans = True
    gate = 0.5

    def __init__(self, params: ShadowParams) -> None:
        self.params = params
        self.reset()

    def reset(self) -> None:
        self._map = ObstacleMap(self.params.map)
        self._recent: deque[tuple[float, str]] = deque()  # (stamp, satellites named) of fixes that used a blocked one
        self._pending: tuple[float, str] = (math.nan, "")  # the last checked fix's stamp and the blocked satellites it used

    def add_scan(self, stamp: float, pose: np.ndarray, points: np.ndarray) -> None:
        """One scan's points (N, 3, base_link) placed with the host's pose (4x4 world<-base_link) at its stamp."""
        self._map.add(stamp, pose, points)

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        if self._map.empty or ctx.antenna is None:
            return Verdict(True, math.nan, "unchecked: no LiDAR map or no position to look from")
        used = [s for s in obs.sats if s.used]
        az = np.array([s.az_deg for s in used], dtype=float)
        el = np.array([s.el_deg for s in used], dtype=float)
        blocked = self._map.blocked(obs.stamp, ctx.antenna, az, el) if used else np.zeros(0, dtype=bool)
        named = ", ".join(f"{getattr(s, 'system', 'GPS')} {s.prn} (az {s.az_deg:.0f}, el {s.el_deg:.0f})" for s, b in zip(used, blocked) if b)
        count = float(blocked.sum())
        self._pending = (obs.stamp, named)
        if count:
            return Verdict(False, count, f"the LiDAR sees {int(count)} used satellite(s) blocked: {named}", on_its_own=True, rule="shadow.blocked")
        while self._recent and self._recent[0][0] < obs.stamp - self.params.hold_s:
            self._recent.popleft()
        if self._recent:
            stamp, held = self._recent[-1]
            why = f"a used satellite was blocked {obs.stamp - stamp:.1f} s ago ({held}; the receiver's filter still carries it)"
            return Verdict(False, 0.0, why, on_its_own=True, rule="shadow.hold")
        return Verdict(True, 0.0, "no used satellite behind what the LiDAR sees")

    def commit(self, obs: FixObservation, verdict: Verdict) -> None:
        stamp, named = self._pending
        if stamp == obs.stamp and named:
            self._recent.append((stamp, named))
