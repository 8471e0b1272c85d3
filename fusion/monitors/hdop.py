"""Monitor 'hdop': the field study's baseline, a threshold on HDOP, satellites and fix quality."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from fusion.monitors.base import FixContext, Monitor
from fusion.observation import FixObservation
from fusion.verdict import Verdict


class HdopParams(BaseModel):
    """Parameters of the 'hdop' monitor (the baseline: HDOP alone)."""

    model_config = ConfigDict(extra="forbid")
    max_hdop: float = Field(2.0, gt=0, description="fixes with a larger HDOP are distrusted [2.0, a common consumer setting]")


class HdopMonitor(Monitor):
    """Trusts a measured fix when its HDOP is at most max_hdop; statistic is the HDOP."""

    name = "hdop"

    def __init__(self, params: HdopParams) -> None:
        self.params = params

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        if obs.hdop > self.params.max_hdop:
            return Verdict(False, obs.hdop, f"HDOP {obs.hdop:.2f} > {self.params.max_hdop:g}", on_its_own=True, rule="hdop.gate")
        return Verdict(True, obs.hdop, "HDOP ok")
