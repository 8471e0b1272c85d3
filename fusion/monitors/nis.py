"""Monitor 'nis': normalised innovation squared of the fix against the filter, chi-square gate."""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field
from scipy.stats import chi2

from fusion.monitors.base import FixContext, Monitor, mahalanobis2
from fusion.observation import FixObservation
from fusion.verdict import Verdict


class NisParams(BaseModel):
    """Parameters of the 'nis' monitor (the filter's normalised innovation squared)."""

    model_config = ConfigDict(extra="forbid")
    gate_prob: float = Field(0.999, gt=0.5, lt=1.0, description="chi-square (2 dof) probability of the gate [0.999, gate at 13.8]")


class NisMonitor(Monitor):
    """Distrusts a fix whose innovation y has y' (HPH' + R)^-1 y above the gate; statistic is that NIS."""

    name = "nis"

    def __init__(self, params: NisParams) -> None:
        self.params = params
        self.gate = float(chi2.ppf(params.gate_prob, 2))

    def check(self, obs: FixObservation, ctx: FixContext) -> Verdict:
        if ctx.predicted is None:
            return Verdict(False, float("nan"), "filter not initialised", rule="nis.uninitialised")
        mean, cov, noise = ctx.predicted
        y = obs.xy - mean
        nis = mahalanobis2(y, cov + noise)
        if math.isnan(nis):
            return Verdict(False, nis, "NIS undefined (filter covariance not finite)", rule="nis.undefined")
        if nis > self.gate:
            return Verdict(False, nis, f"NIS {nis:.1f} > gate {self.gate:.1f}", rule="nis.gate")
        return Verdict(True, nis, "NIS ok")
