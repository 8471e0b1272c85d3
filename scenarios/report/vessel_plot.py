"""The report's vessel figure: clearance to the nearest structure and cross-track error over the run (from vessel.csv)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from riverbench.atomic import atomic_path
from scenarios.report import plots

CAPTION = (
    "Clearance between the hull and the nearest structure (top; the dashed line is the scenario's threshold, "
    "a cross marks a collision) and the true cross-track error against the route (bottom)."
)


def write(run_dir: Path, threshold_m: float, outcome: dict) -> dict[str, str]:
    """plots/vessel.png from vessel.csv ({relative path: caption}; nothing when the run has no vessel track)."""
    path = run_dir / "vessel.csv"
    if not path.exists():
        return {}
    data = plots.read_csv(path)
    t = np.asarray(data.get("t", []), dtype=float)
    if len(t) < 2:
        return {}
    t = t - t[0]
    clearance, cross = np.asarray(data["clearance_m"], float), np.asarray(data["cross_track_m"], float)
    figure = Figure(figsize=(plots.WIDTH_IN, 4.6), layout="constrained")
    figure.suptitle("Vessel: clearance to the nearest structure and cross-track error", fontsize=10)
    top, bottom = figure.subplots(2, 1, sharex=True)
    top.plot(t, clearance, color="tab:blue", lw=1.2, label="clearance (hull to nearest structure)")
    top.axhline(threshold_m, color="tab:red", ls="--", lw=0.8, label=f"threshold {threshold_m:g} m")
    if outcome.get("collisions"):
        top.plot(outcome["collision_t"] - float(data["t"][0]), 0.0, "x", color="tab:red", ms=10, mew=2, ls="none", label="collision")
    top.set_ylabel("clearance (m)")
    top.set_ylim(0.0, min(float(np.nanmax(clearance)) * 1.05 + 0.5, 60.0))
    bottom.plot(t, cross, color="tab:green", lw=1.2, label="cross-track (true offset from the route, left +)")
    bottom.axhline(0.0, color="0.6", lw=0.6)
    bottom.set_ylabel("cross-track (m)")
    bottom.set_xlabel("time since the first scan (s)")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    with atomic_path(run_dir / "plots" / "vessel.png") as tmp:
        figure.savefig(tmp, format="png", dpi=plots.DPI)
        tmp.chmod(plots.FILE_MODE)
    return {"plots/vessel.png": CAPTION}
