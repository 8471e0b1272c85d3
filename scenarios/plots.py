"""The run report's figures, drawn from a run directory's data files.

Figures are plain matplotlib `Figure` objects rendered by Agg (no pyplot, so no global figure
registry and no display needed). Times on every x axis are seconds since the run's first scan.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch

from scenarios.atomic import atomic_path

WINDOW_COLOURS = {"blackout": "#d62728", "nlos": "#ff7f0e", "reacquisition": "#e6c229", "injected": "#9467bd"}
"""Shading and highlight colour of each GPS-degradation window kind."""
MAP_WINDOWS = ("blackout", "nlos", "injected")
"""Window kinds highlighted on the map (re-acquisition follows every blackout and would hide it)."""
QUALITY_STYLE = {1: ("GPS fix: measured", "#1f77b4"), 6: ("GPS fix: receiver dead reckoning", "#8c564b")}
TRACK_COLOURS = ("#2ca02c", "#1f77b4", "#d62728", "#9467bd", "#e377c2", "#17becf", "#ff7f0e", "#8c564b", "#bcbd22", "#7f7f7f")
FAULT_M = 5.0
"""A measured fix whose true error exceeds this is faulty (as in scenarios.metrics)."""
WIDTH_IN = 11.0
DPI = 100
PLOTS = {
    "map": "The stretch: true track, GPS fixes, each estimate and matcher odometry; blackout, NLOS and injected-fault stretches highlighted.",
    "error": "Horizontal error against time: each estimator (lines) and each GPS fix (dots); GPS-degradation windows shaded.",
    "hdop_error": "HDOP against the true horizontal error of each fix: NLOS fixes are not the high-HDOP ones.",
    "yaw": "Yaw error (estimate minus truth, wrapped to ±180°) against time; windows shaded.",
    "matchers": "Scan matchers: points per scan and the outcome of each registration.",
}
"""Each figure's file stem and caption, in report order."""


@dataclass(frozen=True)
class Track:
    """Planar poses at times t: position x, y (world ENU, m) and yaw (rad)."""

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    yaw: np.ndarray


@dataclass(frozen=True)
class Window:
    """One row of windows.csv: a GPS-degradation window."""

    kind: str
    start: float
    end: float


@dataclass(frozen=True)
class RunSeries:
    """The time series of a run directory that the figures draw."""

    t0: float
    truth: Track
    estimates: dict[str, Track]
    matchers: dict[str, Track]
    gps: dict[str, np.ndarray]
    scans: dict[str, np.ndarray]
    windows: list[Window]
    hdop_limits: dict[str, float]


def load(run_dir: Path, estimator_ids: list[str], matcher_ids: list[str], hdop_limits: dict[str, float]) -> RunSeries:
    """Read the trajectories, gps.csv, scans.csv and windows.csv of a run directory."""
    truth = read_tum(run_dir / "groundtruth.tum")
    windows = read_csv(run_dir / "windows.csv")
    return RunSeries(
        t0=float(truth.t[0]) if len(truth.t) else 0.0,
        truth=truth,
        estimates={e: read_tum(run_dir / f"{e}.tum") for e in estimator_ids},
        matchers={m: read_tum(run_dir / f"{m}.tum") for m in matcher_ids},
        gps=read_csv(run_dir / "gps.csv"),
        scans=read_csv(run_dir / "scans.csv"),
        windows=[Window(k, float(s), float(e)) for k, s, e in zip(windows.get("kind", []), windows.get("start", []), windows.get("end", []))],
        hdop_limits=hdop_limits,
    )


def read_tum(path: Path) -> Track:
    """A TUM file as a planar Track (empty when the file is missing or has no rows)."""
    rows = np.loadtxt(path, comments="#", ndmin=2) if path.exists() else np.zeros((0, 8))
    rows = rows if rows.size else np.zeros((0, 8))
    qx, qy, qz, qw = rows[:, 4:8].T
    yaw = np.arctan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy**2 + qz**2))
    return Track(rows[:, 0], rows[:, 1], rows[:, 2], yaw)


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """A CSV file's columns by header name: numbers as float arrays (empty cells NaN), text columns as str arrays."""
    if not path.exists():
        return {}
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    if not rows:
        return {}
    columns = zip(*rows[1:]) if len(rows) > 1 else ([] for _ in rows[0])
    return {name: _column(list(values)) for name, values in zip(rows[0], columns)}


def _column(values: list[str]) -> np.ndarray:
    """A float array of `values` ('' as NaN), or the strings themselves when they are not numbers."""
    try:
        return np.array([float(v) if v else math.nan for v in values], dtype=float)
    except ValueError:
        return np.array(values, dtype=str)


def horizontal_error(track: Track, truth: Track) -> np.ndarray:
    """Horizontal distance (m) from each pose of `track` to the truth at the same time."""
    i = truth_index(truth, track.t)
    return np.hypot(track.x - truth.x[i], track.y - truth.y[i])


def yaw_error_deg(track: Track, truth: Track) -> np.ndarray:
    """Signed yaw error (deg), estimate minus truth, wrapped to [-180, 180)."""
    d = track.yaw - truth.yaw[truth_index(truth, track.t)]
    return np.degrees((d + np.pi) % (2 * np.pi) - np.pi)


def truth_index(truth: Track, t: np.ndarray) -> np.ndarray:
    """Index of the truth pose nearest in time to each of `t`."""
    if not len(truth.t):
        return np.zeros(len(t), dtype=int)
    return np.rint(np.interp(t, truth.t, np.arange(len(truth.t)))).astype(int)


def colours(series: RunSeries) -> dict[str, str]:
    """A fixed colour per estimator and matcher id, the same in every figure."""
    ids = [*series.estimates, *series.matchers]
    return {name: TRACK_COLOURS[i % len(TRACK_COLOURS)] for i, name in enumerate(ids)}


def write_all(series: RunSeries, plots_dir: Path) -> dict[str, str]:
    """Draw every figure that has data into plots_dir/<stem>.png; returns {relative path: caption}."""
    drawers = {"map": map_figure, "error": error_figure, "hdop_error": hdop_figure, "yaw": yaw_figure, "matchers": matchers_figure}
    written = {}
    for stem, draw in drawers.items():
        figure = draw(series)
        if figure is None:
            continue
        with atomic_path(plots_dir / f"{stem}.png") as tmp:
            figure.savefig(tmp, format="png", dpi=DPI)
        written[f"plots/{stem}.png"] = PLOTS[stem]
    return written


def _figure(height_in: float, rows: int = 1, **grid) -> tuple[Figure, list]:
    """A figure of the report's width with `rows` stacked axes sharing x."""
    figure = Figure(figsize=(WIDTH_IN, height_in), layout="constrained")
    axes = figure.subplots(rows, 1, sharex=rows > 1, squeeze=False, **grid)[:, 0]
    return figure, list(axes)


def map_figure(series: RunSeries) -> Figure | None:
    """Top view: true track (black), GPS fixes by quality, each estimate and odometry, windows highlighted."""
    truth = series.truth
    if not len(truth.t):
        return None
    width, height = np.ptp(truth.x), np.ptp(truth.y)
    pad = max(20.0, 0.05 * max(width, height))
    aspect = (height + 2 * pad) / (width + 2 * pad)
    figure, (ax,) = _figure(float(np.clip(WIDTH_IN * aspect * 0.8 + 1.0, 4.5, 11.0)))
    quality = series.gps.get("quality", np.zeros(0))
    for q, (label, colour) in QUALITY_STYLE.items():
        keep = quality == q
        if keep.any():
            ax.scatter(series.gps["e"][keep], series.gps["n"][keep], s=6, color=colour, alpha=0.45, lw=0, label=label, zorder=2)
    ax.plot(truth.x, truth.y, color="black", lw=1.6, label="truth", zorder=3)
    for kind in MAP_WINDOWS:
        _highlight_windows(ax, series, kind)
    palette = colours(series)
    for name, track in series.estimates.items():
        ax.plot(track.x, track.y, color=palette[name], lw=1.1, label=name, zorder=4)
    for name, track in series.matchers.items():
        ax.plot(track.x, track.y, color=palette[name], lw=1.0, ls="--", label=f"{name} (odometry)", zorder=4)
    ax.plot(truth.x[0], truth.y[0], marker="o", ms=9, mfc="white", mec="black", mew=2, ls="none", label="start", zorder=6)
    ax.plot(truth.x[-1], truth.y[-1], marker="s", ms=8, mfc="black", mec="black", ls="none", label="end", zorder=6)
    ax.set_xlim(truth.x.min() - pad, truth.x.max() + pad)
    ax.set_ylim(truth.y.min() - pad, truth.y.max() + pad)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8, framealpha=0.9, markerscale=2)
    ax.set_title("Map (tracks outside the frame are clipped)", fontsize=10)
    return figure


def _highlight_windows(ax, series: RunSeries, kind: str) -> None:
    """Overlay the true track inside each window of `kind` as a thick translucent line (one legend entry)."""
    truth = series.truth
    label = f"{kind} (truth inside)"
    for window in (w for w in series.windows if w.kind == kind):
        inside = (truth.t >= window.start) & (truth.t <= window.end)
        ax.plot(truth.x[inside], truth.y[inside], color=WINDOW_COLOURS[kind], lw=7, alpha=0.55, solid_capstyle="butt", label=label, zorder=2.5)
        label = None


def shade_windows(ax, series: RunSeries) -> list[Patch]:
    """Shade every window on a time axis; returns one legend patch per kind present."""
    present = []
    for window in series.windows:
        ax.axvspan(window.start - series.t0, window.end - series.t0, color=WINDOW_COLOURS.get(window.kind, "grey"), alpha=0.15, lw=0)
        if window.kind not in present:
            present.append(window.kind)
    return [Patch(color=WINDOW_COLOURS.get(k, "grey"), alpha=0.3, label=k) for k in present]


def clip_limit(values: list[np.ndarray], floor: float) -> float:
    """An axis limit that keeps one divergent series from flattening the rest: 1.2 x the 99th percentile."""
    finite = np.concatenate([v[np.isfinite(v)] for v in values]) if values else np.zeros(0)
    return max(floor, 1.2 * float(np.percentile(finite, 99))) if len(finite) else floor


def error_figure(series: RunSeries) -> Figure | None:
    """Horizontal error of every estimator and of every GPS fix against time, windows shaded."""
    if not series.estimates and "err_h" not in series.gps:
        return None
    figure, (ax,) = _figure(4.8)
    patches = shade_windows(ax, series)
    palette = colours(series)
    errors = {name: horizontal_error(track, series.truth) for name, track in series.estimates.items()}
    fix_error = series.gps.get("err_h", np.zeros(0))
    handles = []
    if len(fix_error):
        ax.scatter(series.gps["t"] - series.t0, fix_error, s=5, color="#555555", alpha=0.5, lw=0, zorder=2)
        handles.append(Line2D([], [], marker="o", ls="none", color="#555555", ms=4, label="GPS fix (true error)"))
    for name, error in errors.items():
        handles += ax.plot(series.estimates[name].t - series.t0, error, color=palette[name], lw=1.2, label=name, zorder=3)
    top = clip_limit([*errors.values(), fix_error], floor=1.0)
    ax.set_ylim(0, top)
    ax.axhline(FAULT_M, color="black", lw=0.8, ls=":")
    clipped = [f"{n} {np.nanmax(e):.0f} m" for n, e in errors.items() if len(e) and np.nanmax(e) > top]
    ax.set_title("Horizontal error" + (f" (axis clipped at {top:.1f} m; peaks: {', '.join(clipped)})" if clipped else "")
                 + f"; dotted: {FAULT_M:g} m", fontsize=10)
    ax.set_xlabel("time since start (s)")
    ax.set_ylabel("horizontal error (m)")
    ax.grid(alpha=0.3)
    ax.legend(handles=[*handles, *patches], loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    return figure


def hdop_figure(series: RunSeries) -> Figure | None:
    """Scatter of HDOP against the true horizontal error of measured fixes, NLOS fixes in another colour."""
    gps = series.gps
    if "hdop" not in gps:
        return None
    measured = (gps["quality"] == 1) & np.isfinite(gps["hdop"]) & np.isfinite(gps["err_h"])
    if not measured.any():
        return None
    nlos = measured & (gps["nlos_used"] == 1)
    clear = measured & ~nlos
    figure, (ax,) = _figure(4.8)
    ax.scatter(gps["hdop"][clear], gps["err_h"][clear], s=9, color="#1f77b4", alpha=0.5, lw=0, label=f"direct signals only ({clear.sum()})")
    ax.scatter(gps["hdop"][nlos], gps["err_h"][nlos], s=14, color="#ff7f0e", alpha=0.8, lw=0, label=f"uses an NLOS signal ({nlos.sum()})")
    ax.axhline(FAULT_M, color="black", lw=0.8, ls=":", label=f"fault threshold {FAULT_M:g} m")
    for name, limit in series.hdop_limits.items():
        ax.axvline(limit, color="#d62728", lw=0.9, ls="--", label=f"{name}: trusts HDOP ≤ {limit:g}")
    r = np.corrcoef(gps["hdop"][measured], gps["err_h"][measured])[0, 1] if measured.sum() > 2 else math.nan
    ax.set_title(f"HDOP against true horizontal error of measured fixes (correlation r = {r:.2f})", fontsize=10)
    ax.set_xlabel("HDOP")
    ax.set_ylabel("true horizontal error (m)")
    ax.set_ylim(0, clip_limit([gps["err_h"][measured]], floor=FAULT_M * 1.2))
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    return figure


def yaw_figure(series: RunSeries) -> Figure | None:
    """Signed yaw error of every estimator and matcher against time, windows shaded."""
    tracks = {**series.estimates, **{f"{m} (odometry)": t for m, t in series.matchers.items()}}
    if not tracks:
        return None
    figure, (ax,) = _figure(4.8)
    patches = shade_windows(ax, series)
    palette = colours(series)
    errors = {name: yaw_error_deg(track, series.truth) for name, track in tracks.items()}
    handles = []
    for (name, error), key in zip(errors.items(), [*series.estimates, *series.matchers]):
        handles += ax.plot(tracks[name].t - series.t0, error, color=palette[key], lw=1.1, ls="--" if key in series.matchers else "-", label=name)
    top = clip_limit([np.abs(e) for e in errors.values()], floor=2.0)
    ax.set_ylim(-top, top)
    ax.axhline(0, color="black", lw=0.6)
    ax.set_title(f"Yaw error (axis ±{top:.1f}°)", fontsize=10)
    ax.set_xlabel("time since start (s)")
    ax.set_ylabel("yaw error (deg)")
    ax.grid(alpha=0.3)
    ax.legend(handles=[*handles, *patches], loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    return figure


def matchers_figure(series: RunSeries) -> Figure | None:
    """Per matcher: points per scan (top) and each registration's outcome over time (bottom strip)."""
    mids = [m for m in series.matchers if f"{m}.ok" in series.scans]
    if not mids:
        return None
    figure, (top, strip) = _figure(5.2, rows=2, height_ratios=[3, 0.4 + 0.35 * len(mids)])
    patches = shade_windows(top, series)
    palette = colours(series)
    t = series.scans["t"] - series.t0
    handles = []
    for m in mids:
        handles += top.plot(t, series.scans[f"{m}.points"], color=palette[m], lw=1.0, label=f"{m}: points per scan")
    top.set_ylabel("points per scan")
    top.set_ylim(bottom=0)
    top.grid(alpha=0.3)
    top.legend(handles=[*handles, *patches], loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    top.set_title("Scan matchers", fontsize=10)
    _outcome_strip(strip, series, mids, t)
    return figure


OUTCOMES = (("matched", "#2ca02c"), ("degenerate", "#e6c229"), ("gated", "#7f7f7f"), ("failed", "#d62728"))
"""Registration outcomes of the matchers strip, in drawing order."""


def _outcome_strip(ax, series: RunSeries, mids: list[str], t: np.ndarray) -> None:
    """One row per matcher: a tick per scan coloured by its outcome (the first scan has no reference)."""
    for row, m in enumerate(mids):
        ok, gated, degenerate = (series.scans[f"{m}.{k}"] == 1 for k in ("ok", "gated", "degenerate"))
        attempted = np.arange(len(t)) > 0
        masks = {"matched": ok & ~degenerate, "degenerate": ok & degenerate, "gated": gated & attempted,
                 "failed": ~ok & ~gated & attempted}
        for name, colour in OUTCOMES:
            ax.vlines(t[masks[name]], row - 0.4, row + 0.4, color=colour, lw=1.0)
    ax.set_yticks(range(len(mids)), mids)
    ax.set_ylim(len(mids) - 0.5, -0.5)
    ax.set_xlabel("time since start (s)")
    ax.legend(handles=[Patch(color=c, label=n) for n, c in OUTCOMES], loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
