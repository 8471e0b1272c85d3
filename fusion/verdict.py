"""What an estimator says about each fix (Verdict) and the anomalies it records (Event)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Verdict:
    """A monitor's decision on one fix: trusted or not, its test statistic (higher = more suspect) and why."""

    trusted: bool
    statistic: float
    reason: str


@dataclass(frozen=True)
class Event:
    """An input the estimator refused or could not use, kept so a run can explain itself."""

    stamp: float
    source: str
    reason: str
