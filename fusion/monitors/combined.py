"""Monitors 'combined' (default nis + consistency) and 'combined_cn0' (default consistency + cn0): distrust a
fix when any member monitor does."""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field

from fusion.monitors.base import FixContext, Monitor
from fusion.observation import FixObservation
from fusion.verdict import Verdict


class CombinedParams(BaseModel):
    """members: monitor names combined by OR; member_params: parameters per member name."""

    model_config = ConfigDict(extra="forbid")
    members: list[str] = Field(default_factory=lambda: ["nis", "consistency"], min_length=1)
    member_params: dict[str, dict] = Field(default_factory=dict)


class CombinedCn0Params(CombinedParams):
    """The same with members consistency + cn0 by default: the best combination measured by
    benchmarks/monitors.py (charles_river and canal_lock, gicp odometry): cn0 catches the fixes that
    use NLOS satellites, consistency the re-acquisition after an outage and displacement jumps."""

    members: list[str] = Field(default_factory=lambda: ["consistency", "cn0"], min_length=1)


class CombinedMonitor(Monitor):
    """OR of its members; statistic is the largest member statistic divided by that member's gate."""

    name = "combined"

    def __init__(self, params: CombinedParams, members: list[Monitor]) -> None:
        self.params = params
        self.members = members

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        verdicts = [m.check(obs, ctx) for m in self.members]
        scaled = [v.statistic / getattr(m, "gate", 1.0) for m, v in zip(self.members, verdicts)]
        finite = [s for s in scaled if not math.isnan(s)]
        statistic = max(finite) if finite else math.nan
        refused = [f"{m.name}: {v.reason}" for m, v in zip(self.members, verdicts) if not v.trusted]
        if refused:
            on_its_own = any(v.on_its_own for v in verdicts if not v.trusted)
            return Verdict(False, statistic, "; ".join(refused), on_its_own=on_its_own)
        return Verdict(True, statistic, "all members trust it")

    def commit(self, obs: FixObservation, verdict: Verdict) -> None:
        for m in self.members:
            m.commit(obs, verdict)

    def reset(self) -> None:
        for m in self.members:
            m.reset()

    def note_outage(self, stamp: float) -> None:
        for m in self.members:
            m.note_outage(stamp)
