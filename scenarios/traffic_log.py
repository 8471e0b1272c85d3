"""What a run keeps of the traffic besides movers.csv: how many points of each scan came from movers."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from scenarios.stream import ScanEvent


class MoverPoints:
    """Counts, per scan of an event stream, the points whose label is a mover's (>= the world's part count)."""

    def __init__(self, first_label: int) -> None:
        self.first_label = first_label
        self.counts: list[int] = []

    def tap(self, events) -> Iterator:
        """The events, unchanged, counting as they pass."""
        for event in events:
            if isinstance(event, ScanEvent):
                self.counts.append(int(np.count_nonzero(event.scan.points["label"] >= self.first_label)))
            yield event

    def metrics(self) -> dict:
        """median, p90 and max points from movers per scan, and the share of scans with any."""
        counts = np.asarray(self.counts, dtype=float)
        if not len(counts):
            return {"median": float("nan"), "p90": float("nan"), "max": float("nan"), "scans_with": float("nan")}
        return {"median": float(np.median(counts)), "p90": float(np.percentile(counts, 90)), "max": float(counts.max()),
                "scans_with": float(np.mean(counts > 0))}
