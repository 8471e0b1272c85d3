"""GPS-degradation windows from the simulator's truth, and how an estimate fared through each.

Kinds: `blackout` (no measured position: the receiver coasts or reports nothing), `nlos` (measured
fixes that used a satellite received only by reflection), `reacquisition` (after a blackout, until
what the environment adds to the receiver's error falls below REACQUIRED_M: its internal filter
smooths a wrong estimate for a while), `injected` (the scenario's forced GPS faults).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from scenarios.score.record import FixTable

KINDS = ("blackout", "nlos", "reacquisition", "injected")
NLOS_MERGE_S = 1.0
"""NLOS stretches at most this far apart are one window."""
REACQUIRED_M = 1.0
"""Re-acquisition ends at the first measured fix whose environment-added error is below this."""
REACQUISITION_MAX_S = 120.0
RECOVERED_MARGIN_M = 1.0
"""An estimate has recovered once its error is back within this of its error at the window's entry."""
SETTLED_M = 2.0
"""An estimate has settled once its error is within this of the truth (issue 39's promise: back within 2 m in 10 s) ..."""
SETTLED_FOR_S = 10.0
"""... and stays within it this long, or until the next window starts or the run ends: an estimate that touches 2 m and
leaves it again within the promise's own horizon has not come back (the full quickstart, seed 0, at 7b0d9ca: within 2 m
at the end of the NLOS window at 1775.9 s, 2.0-2.2 m off until 1790 s and 4.5 m at 1791 s; counted at its first touch,
0 s). A window that starts as another ends (re-acquisition after a blackout) leaves the first one's return nothing to
last through: there the first touch counts, and the next window's own settle tells the rest."""


@dataclass(frozen=True)
class Window:
    kind: str
    start: float
    end: float

    @property
    def duration(self) -> float:
        return self.end - self.start

    def scans(self, t: np.ndarray) -> np.ndarray:
        """Which scans at times `t` the window's fixes shaped: those in (start, end]. At equal stamps a scan is fed before
        the fix (scenarios.pipeline.stream), so the scan at `start` has not seen the window's first fix and the one at `end`
        has not seen the fix that ends it. [start, end) made a metric jump when a fix moved 1e-10 s past its scan
        (issue 41: gps_only's re-acquisition max error on quickstart [fast] 22.8 -> 8.3 m, the blackout's last scan
        counted as re-acquisition)."""
        return (t > self.start) & (t <= self.end)


def find(fixes: FixTable, injected: list[tuple[float, float]], period_s: float) -> list[Window]:
    """Every window of the run, sorted by start; a window ends at the first fix after it."""
    t = fixes.t
    out: list[Window] = []
    blackouts = _runs(t, ~fixes.measured, period_s, 0.0)
    out += [Window("blackout", a, b) for a, b in blackouts]
    out += [Window("nlos", a, b) for a, b in _runs(t, fixes.nlos_used, period_s, NLOS_MERGE_S)]
    added = fixes.added_error
    for _, end in blackouts:
        after = np.nonzero((t >= end) & (t < end + REACQUISITION_MAX_S) & fixes.measured)[0]
        if not len(after):
            continue
        done = after[added[after] < REACQUIRED_M]
        stop = float(t[done[0]]) if len(done) else float(min(t[after[-1]] + period_s, end + REACQUISITION_MAX_S))
        if stop > end:
            out.append(Window("reacquisition", float(end), stop))
    out += [Window("injected", float(a), float(b)) for a, b in injected if b > t[0] and a < t[-1] + period_s] if len(t) else []
    return sorted(out, key=lambda w: (w.start, KINDS.index(w.kind)))


def _runs(t: np.ndarray, flag: np.ndarray, period_s: float, merge_s: float) -> list[tuple[float, float]]:
    """[start, end) of each run of flagged epochs (end: the next epoch), runs closer than merge_s merged."""
    runs: list[list[float]] = []
    for i in np.nonzero(flag)[0]:
        start, end = float(t[i]), float(t[i + 1]) if i + 1 < len(t) else float(t[i] + period_s)
        if runs and start - runs[-1][1] <= merge_s + 1e-9:
            runs[-1][1] = end
        else:
            runs.append([start, end])
    return [(a, b) for a, b in runs]


@dataclass(frozen=True)
class Passage:
    """One estimate through one window: the largest error inside it (Window.scans) or at its exit (the
    first scan after it), at entry (the last scan before it) and exit, what the window added
    (exit - entry), the time after the window until the error is back within
    RECOVERED_MARGIN_M of its entry value and the time until it is within SETTLED_M of the truth to stay there for
    SETTLED_FOR_S (0 when it never left it; NaN: not within the run)."""

    max_error: float
    entry_error: float
    exit_error: float
    added: float
    recover_s: float
    settle_s: float


def next_start(window: Window, windows: list[Window]) -> float:
    """When the first of `windows` after `window` starts (inf: none does)."""
    return min((w.start for w in windows if w.start >= window.end and w is not window), default=math.inf)


def settled_from(t: np.ndarray, error: np.ndarray, after: np.ndarray, until: float) -> float:
    """The first time among the scans `after` (indices, in time order) from which the error is within SETTLED_M and
    stays within it for SETTLED_FOR_S or until `until` (the next window's start) or the run's end; NaN: none."""
    out = ~(error <= SETTLED_M)  # NaN counts as out
    exceed = np.flatnonzero(out)
    within = after[~out[after]]
    j = np.searchsorted(exceed, within)  # the first scan out after each
    leaves = t[exceed[np.minimum(j, len(exceed) - 1)]] if len(exceed) else np.full(len(within), math.inf)
    lasts = (j == len(exceed)) | (leaves >= np.minimum(t[within] + SETTLED_FOR_S, until))
    return float(t[within[np.argmax(lasts)]]) if lasts.any() else math.nan


def passage(window: Window, t: np.ndarray, error: np.ndarray, until: float = math.inf) -> Passage:
    """How an estimate with horizontal `error` at scan times `t` went through `window` (`until`: when the next window
    starts, where settling need last no longer)."""
    nan = float("nan")
    inside = window.scans(t)
    before = np.nonzero(t <= window.start)[0]
    after = np.nonzero(t > window.end)[0]
    entry = float(error[before[-1]]) if len(before) else (float(error[inside][0]) if inside.any() else nan)
    span = error[inside]
    exit_error = float(error[after[0]]) if len(after) else (float(span[-1]) if len(span) else nan)
    max_error = float(np.nanmax(np.r_[span, exit_error])) if np.isfinite(np.r_[span, exit_error]).any() else nan
    recover = nan
    if len(after) and np.isfinite(entry):
        back = after[error[after] <= entry + RECOVERED_MARGIN_M]
        if len(back):
            recover = max(0.0, float(t[back[0]] - window.end))
    settled = settled_from(t, error, after, until)
    settle = max(0.0, settled - window.end) if math.isfinite(settled) else nan
    return Passage(max_error, entry, exit_error, exit_error - entry, recover, settle)
