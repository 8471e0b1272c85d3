"""What the vessel did, from the truth: clearance to every structure, cross-track error, how the run ended.

Kept once per control period (a LiDAR revolution) in open and closed loop alike; contact is
searched at the integration steps of any period that came near a structure, so a collision is
found when the hull first touches, not a revolution later.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from sim.clearance import Clearance, HullClearance

NEAR_M = 1.0
"""Within this clearance (plus the period's travel) contact is searched step by step."""
FINE_STEP_S = 0.01
"""Time step of that search (2.4 cm at full speed)."""
OUTCOMES = ("completed", "collision", "time_limit", "interrupted")
"""How a run's vessel track can end (`interrupted`: the run stopped for another reason, e.g. a failed simulation)."""


@dataclass(frozen=True)
class Contact:
    """The hull touched world part `part` (its name and kind) at time t."""

    t: float
    part: str
    kind: str


@dataclass
class VesselLog:
    """Per period: t, true x, y, yaw, station, cross-track (left +), clearance and its nearest part, the commands."""

    rows: list[tuple] = field(default_factory=list)
    contact: Contact | None = None
    outcome: str = "interrupted"

    COLUMNS = ("t", "x", "y", "yaw", "station_m", "cross_track_m", "clearance_m", "nearest_part", "cmd_left", "cmd_right")

    def add(
        self,
        t: float,
        pose: np.ndarray,
        station: float,
        cross: float,
        clearance: Clearance,
        part: str,
        commands: tuple[float, float] = (np.nan, np.nan),
    ) -> None:
        yaw = float(np.arctan2(pose[1, 0], pose[0, 0]))
        self.rows.append((t, float(pose[0, 3]), float(pose[1, 3]), yaw, station, cross, clearance.distance_m, part, *commands))

    def column(self, name: str) -> np.ndarray:
        i = self.COLUMNS.index(name)
        return np.array([r[i] for r in self.rows], dtype=object if name == "nearest_part" else float)


class VesselWatch:
    """Checks the true hull against the world each period: logs clearance and cross-track, finds contact."""

    def __init__(self, world, trajectory, clearance: HullClearance, period_s: float):
        self.world, self.trajectory, self.clearance, self.period_s = world, trajectory, clearance, period_s
        self.route = world.route
        self.log = VesselLog()

    def period(self, t0: float, t1: float, commands: tuple[float, float] = (np.nan, np.nan)) -> Contact | None:
        """Log the state at t0 and look for contact in (t0, t1]; the contact (also kept in the log) or None."""
        pose = self.trajectory.pose(t0)
        (at_start,) = self.clearance.at(pose)
        station, cross, _ = self.route.project(pose[:2, 3])
        nearest = self.world.parts[at_start.part].name if at_start.part >= 0 else ""
        self.log.add(t0, pose, float(station), float(cross), at_start, nearest, commands)
        travel = float(np.max(self.trajectory.speed(t1))) * (t1 - t0)
        if at_start.distance_m > NEAR_M + travel:  # no hull point moves farther than travel within the period (NEAR_M's margin holds the turn)
            return None
        ts = np.linspace(t0, t1, max(int(np.ceil((t1 - t0) / FINE_STEP_S)), 1) + 1)
        for t, c in zip(ts, self.clearance.at(self.trajectory.poses(ts))):
            if self.clearance.touching(c):
                part = self.world.parts[c.part]
                self.log.contact = Contact(float(t), part.name, part.kind)
                self.log.outcome = "collision"
                return self.log.contact
        return None


def metrics(log: VesselLog, threshold_m: float, period_s: float) -> dict:
    """The `vessel` node of metrics.json: clearance, time under the threshold, collision, cross-track error."""
    clearance = log.column("clearance_m")
    cross = np.abs(log.column("cross_track_m"))
    finite = clearance[np.isfinite(clearance)]
    i = int(np.argmin(clearance)) if len(finite) else -1
    return {
        "outcome": log.outcome,
        "completed": int(log.outcome == "completed"),  # 0/1, so that expectations can read it
        "collisions": int(log.contact is not None),
        "collision_t": log.contact.t if log.contact else float("nan"),
        "collision_part": log.contact.part if log.contact else "",
        "collision_kind": log.contact.kind if log.contact else "",
        "min_clearance_m": 0.0 if log.contact else (float(finite.min()) if len(finite) else float("inf")),
        "min_clearance_part": log.contact.part if log.contact else (log.column("nearest_part")[i] if i >= 0 else ""),
        "min_clearance_t": log.contact.t if log.contact else (float(log.column("t")[i]) if i >= 0 else float("nan")),
        "clearance_threshold_m": threshold_m,
        "time_below_threshold_s": float(np.sum(clearance < threshold_m) * period_s),
        "cross_track": _stats(cross),
        "distance_m": float(np.sum(np.hypot(np.diff(log.column("x")), np.diff(log.column("y"))))) if len(log.rows) > 1 else 0.0,
    }


def _stats(values: np.ndarray) -> dict:
    if not len(values):
        return {"mean": float("nan"), "p95": float("nan"), "max": float("nan")}
    return {"mean": float(values.mean()), "p95": float(np.percentile(values, 95)), "max": float(values.max())}
