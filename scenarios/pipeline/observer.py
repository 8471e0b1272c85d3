"""The hooks a run offers a watcher (the live view, scenarios.view): called as the run streams, never needed by it.

A run without an observer does no extra work: the Feed and the runner only check that none was given.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Protocol

import numpy as np

if TYPE_CHECKING:
    from fusion.verdict import Verdict
    from scenarios.pipeline.assembly import Assembly
    from scenarios.pipeline.stream import ScanEvent
    from sim.gnss_fix import GnssFix


class RunObserver(Protocol):
    """Told of a run's world once, then of each scan and fix in time order, then that the run ended."""

    def begin(self, stack: Assembly, run_dir: Path) -> None:
        """The run's assembled stack, before the first event; `run_dir` is the (temporary) run directory being written."""

    def scan(self, event: ScanEvent, truth: np.ndarray, estimates: dict[str, np.ndarray]) -> None:
        """A scan once the estimators have it: the true base_link pose at its stamp and each estimator's pose
        (4x4 world<-base_link, NaN when it has none)."""

    def fix(self, fix: GnssFix, verdicts: dict[str, Verdict]) -> None:
        """A fix once the estimators have it, with each live estimator's verdict on it."""

    def close(self, keep: bool) -> None:
        """The run ended: `keep` when it finished and its outputs stay, False when it failed (nothing is kept).
        Called again after a close it must do nothing."""
