"""Monitors 'combined' (default nis + consistency), 'combined_cn0' (default consistency + cn0) and 'combined_shadow'
(default consistency + shadow): distrust a fix when any member monitor does. The verdict is on the
fix's own evidence only when every refusing member's is (a member that finds the fix at odds with the filter speaks for
divergence), and steady when every member's is (fusion.Verdict)."""

from __future__ import annotations

import math

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from fusion.monitors.base import FixContext, Monitor
from fusion.observation import FixObservation
from fusion.verdict import Verdict


class CombinedParams(BaseModel):
    """Parameters of the 'combined' monitor: which monitors it ORs and their parameters."""

    model_config = ConfigDict(extra="forbid")
    members: list[str] = Field(
        default_factory=lambda: ["nis", "consistency"], min_length=1, description="monitor names combined by OR [nis, consistency]"
    )
    member_params: dict[str, dict] = Field(default_factory=dict, description="parameters per member name [{}: each member's defaults]")


class CombinedCn0Params(CombinedParams):
    """Parameters of the 'combined_cn0' monitor: 'combined' with consistency + cn0 as its default members."""

    members: list[str] = Field(
        default_factory=lambda: ["consistency", "cn0"],
        min_length=1,
        description="monitor names combined by OR [consistency, cn0: the best combination measured by "
        "benchmarks/monitors.py (charles_river and canal_lock, gicp odometry): cn0 catches the fixes that use NLOS "
        "satellites, consistency the re-acquisition after an outage and displacement jumps]",
    )


class CombinedShadowParams(CombinedParams):
    """Parameters of the 'combined_shadow' monitor: 'combined' with consistency + shadow as its default members."""

    members: list[str] = Field(
        default_factory=lambda: ["consistency", "shadow"],
        min_length=1,
        description="monitor names combined by OR [consistency, shadow: the LiDAR's map of what stands above the water "
        "tells a satellite behind a quay or a facade (shadow) without refusing the direct signals a tree crown "
        "attenuates, which C/N0 cannot tell from a reflection's loss; consistency catches the re-acquisition after an "
        "outage, displacement jumps and a receiver's walk-back]",
    )


class CombinedMonitor(Monitor):
    """OR of its members; statistic is the largest member statistic divided by that member's gate."""

    name = "combined"

    def __init__(self, params: CombinedParams, members: list[Monitor]) -> None:
        self.params = params
        self.members = members
        self.wants_scans = any(m.wants_scans for m in members)

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        verdicts = [m.check(obs, ctx) for m in self.members]
        scaled = [v.statistic / getattr(m, "gate", 1.0) for m, v in zip(self.members, verdicts)]
        finite = [s for s in scaled if not math.isnan(s)]
        statistic = max(finite) if finite else math.nan
        refused = [f"{m.name}: {v.reason}" for m, v in zip(self.members, verdicts) if not v.trusted]
        if refused:
            on_its_own = all(v.on_its_own for v in verdicts if not v.trusted)  # a member that disagrees with the filter speaks for divergence
            rule = "+".join(v.rule or m.name for m, v in zip(self.members, verdicts) if not v.trusted)
            return Verdict(False, statistic, "; ".join(refused), on_its_own=on_its_own, rule=rule, steady=all(v.steady for v in verdicts))
        allowed = [(m, v) for m, v in zip(self.members, verdicts) if v.allowance_m > 0]
        if allowed:  # independent allowances add in quadrature
            allowance = math.sqrt(sum(v.allowance_m**2 for _, v in allowed))
            rule = "+".join(v.rule or m.name for m, v in allowed)
            reason = "; ".join(f"{m.name}: {v.reason}" for m, v in allowed)
            return Verdict(True, statistic, reason, rule=rule, allowance_m=allowance, steady=all(v.steady for v in verdicts))
        return Verdict(True, statistic, "all members trust it", steady=all(v.steady for v in verdicts))

    def commit(self, obs: FixObservation, verdict: Verdict) -> None:
        for m in self.members:
            m.commit(obs, verdict)

    def reset(self) -> None:
        for m in self.members:
            m.reset()

    def add_scan(self, stamp: float, pose: np.ndarray, points: np.ndarray) -> None:
        for m in self.members:
            if m.wants_scans:
                m.add_scan(stamp, pose, points)

    def note_outage(self, stamp: float) -> None:
        for m in self.members:
            m.note_outage(stamp)
