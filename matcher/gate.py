"""The scan gate: drop a revolution whose point count is too low or jumps from the recent good ones."""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field


class GateParams(BaseModel):
    """Scan-gate settings shared by every matcher."""

    model_config = ConfigDict(extra="forbid")

    gate_min_points: int = Field(500, ge=0, description="drop scans with fewer usable points (default 500)")
    gate_max_ratio: float = Field(
        2.0, gt=1.0, description="drop scans whose count differs from the recent median by more than this factor (default 2)"
    )
    gate_window: int = Field(5, ge=1, description="number of recent accepted scans whose median count is the reference (default 5)")
    gate_reset_after: int = Field(
        5, ge=1, description="after this many consecutive ratio drops, accept the new count level (a real scene change; default 5)"
    )


@dataclass(frozen=True)
class GateVerdict:
    ok: bool
    reason: str = ""


class ScanGate:
    """Point-count gate (the field study's extra stage against momentary blinding)."""

    def __init__(self, params: GateParams) -> None:
        self._p = params
        self._recent: deque[int] = deque(maxlen=params.gate_window)
        self._ratio_drops = 0

    @property
    def reference_count(self) -> float | None:
        """Median point count of the recent accepted scans (None before the first)."""
        return float(np.median(self._recent)) if self._recent else None

    def check(self, n_points: int) -> GateVerdict:
        """Verdict for a scan with n_points usable points; accepted scans update the reference."""
        p = self._p
        if n_points < max(p.gate_min_points, 1):
            return GateVerdict(False, f"too few points: {n_points} < gate_min_points {p.gate_min_points}")
        ref = self.reference_count
        if ref is not None:
            ratio = max(n_points / ref, ref / n_points)
            if ratio > p.gate_max_ratio:
                self._ratio_drops += 1
                if self._ratio_drops < p.gate_reset_after:
                    return GateVerdict(
                        False,
                        f"point count jump: {n_points} vs recent median {ref:.0f} (ratio {ratio:.2f} > gate_max_ratio {p.gate_max_ratio})",
                    )
                self._recent.clear()
        self._ratio_drops = 0
        self._recent.append(n_points)
        return GateVerdict(True)
