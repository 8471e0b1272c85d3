"""Where a replay's matcher odometry starts: a scan matcher measures motion only, so its chained track is laid
onto the world at one scan, on an estimator's pose there. That pose must carry a heading, or the whole track turns
about the start (a heading of 0 put gicp's replayed track 11-19 m off): the first scan at which an estimator
knows its heading to HEADING_SD_DEG (a fused estimator once aligned: their alignment asks 5 deg), else the first
at which one knows it to COURSE_SD_DEG (gps_only's GPS course over ground, once the boat has moved), else none
(position only: the track keeps the matcher's own axes, and the replay says so)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from scenarios.score.record import RunRecord

HEADING_SD_DEG = 10.0
COURSE_SD_DEG = 45.0


@dataclass
class HeadingLog:
    """Each estimator's heading standard deviation (deg) at each scan, read through `sd_of` when called after each scan."""

    estimator_ids: list[str]
    sd_of: Callable[[str], float] | None = None  # each estimator's, once the Feed exists
    sd: dict[str, list[float]] = field(default_factory=dict)

    def __call__(self, stamp: float, results: dict | None = None) -> None:
        for eid in self.estimator_ids:
            self.sd.setdefault(eid, []).append(self.sd_of(eid) if self.sd_of is not None else math.nan)


def yaw_sd_deg(cov: np.ndarray | None) -> float:
    """The heading standard deviation (deg) of a 6x6 [x, y, z, roll, pitch, yaw] covariance (NaN without one)."""
    return math.degrees(math.sqrt(cov[5, 5])) if cov is not None and cov[5, 5] >= 0 else math.nan


@dataclass(frozen=True)
class Anchor:
    """The estimate a matcher track is laid on: its scan index, estimator, and what its heading is."""

    index: int
    estimator: str
    heading: str  # "estimate", "course over ground" or "none"

    def describe(self, stamp: float) -> dict:
        return {"estimator": self.estimator, "t": stamp, "heading": self.heading}


def choose(rec: RunRecord, log: HeadingLog) -> Anchor | None:
    """The first estimate with a heading (see the module docstring), else the first estimate at all; None without any."""
    finite = {eid: np.isfinite(rec.estimates[eid]).all(axis=(1, 2)) for eid in log.estimator_ids}
    for bound, heading in ((HEADING_SD_DEG, "estimate"), (COURSE_SD_DEG, "course over ground"), (math.inf, "none")):
        firsts = []
        for order, eid in enumerate(log.estimator_ids):
            sd = np.asarray(log.sd.get(eid, []), dtype=float)
            ok = finite[eid][: len(sd)] & (sd <= bound) if math.isfinite(bound) else finite[eid]
            if ok.any():
                firsts.append((int(np.argmax(ok)), order, eid))
        if firsts:
            index, _, eid = min(firsts)
            return Anchor(index, eid, heading)
    return None


def anchored(rec: RunRecord, anchor: Anchor | None) -> RunRecord:
    """The record with each matcher's odometry (chained from identity) laid onto the anchor's estimate at the matcher's first
    pose at or after the anchor's scan: the whole pose, or only its position when the anchor has no heading."""
    if anchor is None:
        return rec
    estimate = rec.estimates[anchor.estimator]
    matches = {}
    for mid, track in rec.matches.items():
        usable = np.isfinite(track.pose).all(axis=(1, 2)) & np.isfinite(estimate).all(axis=(1, 2))
        usable[: anchor.index] = False
        if not usable.any():
            matches[mid] = track
            continue
        k = int(np.argmax(usable))
        move = estimate[k] @ np.linalg.inv(track.pose[k])
        if anchor.heading == "none":
            move = np.eye(4)
            move[:3, 3] = estimate[k][:3, 3] - track.pose[k][:3, 3]
        matches[mid] = dataclasses.replace(track, pose=move @ track.pose)
    return dataclasses.replace(rec, matches=matches)
