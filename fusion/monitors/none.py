"""Monitor 'none': trust every measured position (for a filter that is robust on its own)."""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from fusion.monitors.base import FixContext, Monitor
from fusion.observation import FixObservation
from fusion.verdict import Verdict


class NoneParams(BaseModel):
    """No parameters."""

    model_config = ConfigDict(extra="forbid")


class NoMonitor(Monitor):
    """Trusts every fix; statistic is 0."""

    name = "none"

    def __init__(self, params: NoneParams) -> None:
        self.params = params

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        return Verdict(True, 0.0, "no monitor")
