"""What an estimator says about each fix (Verdict) and the anomalies it records (Event)."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Verdict:
    """A monitor's decision on one fix: trusted or not, its test statistic (higher = more suspect), why,
    and whether it was refused on its own evidence."""

    trusted: bool
    statistic: float
    reason: str
    on_its_own: bool = False
    """Refused on the fix's own evidence (C/N0, HDOP), not for disagreeing with the filter: it says
    nothing about the filter having diverged, so it does not count towards a re-lock."""


@dataclass(frozen=True)
class Event:
    """An input the estimator refused or could not use, kept so a run can explain itself."""

    stamp: float
    source: str
    reason: str
