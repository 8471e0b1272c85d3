"""Stanford diagrams: each epoch's horizontal error against its protection level, coloured by how many epochs fall in a cell.

The standard picture of an integrity bound (Tossaint, Samson, Toran, Ventura-Traveset, Hernandez-Pajares, Juan, Sanz
and Ramos-Bosch 2007, "The Stanford - ESA Integrity Diagram: a new tool for the user domain SBAS integrity
assessment", Navigation 54(2):153-162): epochs above the diagonal (error > HPL) are misleading information, those with
the error above the alert limit while HPL was below it hazardous, those with HPL above the alert limit unavailable.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure

CELLS = 60
"""Cells per axis."""


@dataclass(frozen=True)
class Epochs:
    """One estimator's epochs: horizontal error and protection level (m), the scans where both are finite."""

    error: np.ndarray
    level: np.ndarray

    @classmethod
    def of(cls, error: np.ndarray, level: np.ndarray) -> Epochs:
        both = np.isfinite(error) & np.isfinite(level)
        return cls(np.asarray(error, dtype=float)[both], np.asarray(level, dtype=float)[both])

    @classmethod
    def pooled(cls, parts: list[Epochs]) -> Epochs:
        return cls(np.concatenate([p.error for p in parts] or [np.zeros(0)]), np.concatenate([p.level for p in parts] or [np.zeros(0)]))


def figure(epochs: dict[str, Epochs], alert_limit_m: float, title: str, width_in: float) -> Figure | None:
    """One panel per estimator with epochs; None when none has any."""
    shown = {name: e for name, e in epochs.items() if len(e.error)}
    if not shown:
        return None
    columns = min(len(shown), 4)
    rows = -(-len(shown) // columns)
    fig = Figure(figsize=(width_in, 3.2 * rows + 0.6), layout="constrained")
    axes = fig.subplots(rows, columns, squeeze=False).ravel()
    # the axes span the errors (a dead-reckoning filter's level can grow without bound): larger values sit in the last cell
    top = max(2.0 * alert_limit_m, *(1.1 * float(np.percentile(e.error, 99.5)) for e in shown.values()))
    edges = np.linspace(0.0, top, CELLS + 1)
    mesh = None
    for ax, (name, e) in zip(axes, shown.items()):
        counts, _, _ = np.histogram2d(np.minimum(e.level, top), np.minimum(e.error, top), bins=(edges, edges))
        mesh = ax.pcolormesh(edges, edges, np.where(counts > 0, counts, np.nan).T, norm=LogNorm(vmin=1, vmax=max(counts.max(), 2)), cmap="viridis")
        ax.plot([0, top], [0, top], color="black", lw=0.8)
        ax.axvline(alert_limit_m, color="black", lw=0.8, ls="--")
        ax.axhline(alert_limit_m, color="black", lw=0.8, ls="--")
        misleading = int(np.sum(e.error > e.level))
        hazardous = int(np.sum((e.error > alert_limit_m) & (e.level < alert_limit_m)))
        unavailable = int(np.sum(e.level >= alert_limit_m))
        ax.set_title(f"{name}: {len(e.error)} epochs", fontsize=9)
        ax.text(
            0.02,
            0.98,
            f"MI {misleading} ({misleading / len(e.error):.2%})\nHMI {hazardous}\nunavailable {unavailable / len(e.error):.1%}",
            transform=ax.transAxes,
            va="top",
            fontsize=8,
            bbox={"facecolor": "white", "alpha": 0.8, "lw": 0},
        )
        ax.set_xlim(0, top)
        ax.set_ylim(0, top)
        ax.set_xlabel("protection level (m)")
        ax.set_ylabel("horizontal error (m)")
    for ax in axes[len(shown) :]:
        ax.set_visible(False)
    if mesh is not None:
        fig.colorbar(mesh, ax=axes[: len(shown)].tolist(), label="epochs per cell", shrink=0.8)
    fig.suptitle(
        f"{title}: error against protection level (alert limit {alert_limit_m:g} m, dashed; above the diagonal: misleading; "
        f"values beyond {top:.0f} m in the last cell)",
        fontsize=10,
    )
    return fig
