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
    rule: str = ""
    """The test that refused the fix, or that trusted it only with an allowance, as `<monitor>.<test>` (e.g. `cn0.hold`,
    `consistency.guard`; a combined monitor's members joined by `+`; `input.<why>` for a fix the estimator could not
    use), "" when trusted outright: what gps.csv records per fix and the report counts false alarms by, so a run shows
    which test refuses good fixes."""
    allowance_m: float = 0.0
    """A trusted fix's error the monitor could not rule out (m, 1 sigma per horizontal axis): the host adds its square
    to the fix's covariance, so the fix weighs in only as far as the filter is less sure than that (0: none)."""
    steady: bool = True
    """The fix moves with the odometry (its displacement from the fix a window earlier passes a tight test) and nothing
    else refused it on the position: a run of such fixes that the filter refuses shows the filter, not the receiver, has
    gone astray, so only such fixes count towards a re-lock and become its point."""


@dataclass(frozen=True)
class Event:
    """An input the estimator refused or could not use, kept so a run can explain itself."""

    stamp: float
    source: str
    reason: str
