"""What a run keeps of its traffic, scan by scan: each mover's pose at the scan's stamp (movers.csv) and how
many of the scan's points came from movers. Taken as the scans pass, so a closed-loop vessel (which keeps only
a recent history) is never asked about its past."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from scenarios.pipeline.stream import ScanEvent


class TrafficLog:
    """Taps an event stream over a sim.Scene: per scan, stamp, mover poses (M, 4, 4) and points from movers."""

    def __init__(self, scene) -> None:
        self.traffic, self.first_label = scene.traffic, len(scene.world.parts)
        self.stamps: list[float] = []
        self.poses: list[np.ndarray] = []
        self.points: list[int] = []

    def tap(self, events) -> Iterator:
        """The events, unchanged, logged as they pass (nothing is logged without traffic)."""
        for event in events:
            if self.traffic and isinstance(event, ScanEvent):
                self.stamps.append(event.stamp)
                self.poses.append(self.traffic.poses([event.stamp])[:, 0])
                self.points.append(int(np.count_nonzero(event.scan.points["label"] >= self.first_label)))
            yield event

    def metrics(self) -> dict:
        """median, p90 and max points from movers per scan, and the share of scans with any."""
        counts = np.asarray(self.points, dtype=float)
        if not len(counts):
            return {"median": float("nan"), "p90": float("nan"), "max": float("nan"), "scans_with": float("nan")}
        return {
            "median": float(np.median(counts)),
            "p90": float(np.percentile(counts, 90)),
            "max": float(counts.max()),
            "scans_with": float(np.mean(counts > 0)),
        }
