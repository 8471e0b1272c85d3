"""The run report's figures, drawn from a run directory's data files.

Figures are plain matplotlib `Figure` objects rendered by Agg (no pyplot, so no global figure
registry and no display needed). Times on every x axis are seconds since the run's first scan.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from matplotlib.collections import PathCollection
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Rectangle

from fusion.observation import POSITION_QUALITIES
from riverbench.angles import wrap_angle
from riverbench.atomic import atomic_path
from scenarios.pipeline import files
from scenarios.report import stanford, world_map

WINDOW_COLOURS = {"blackout": "#d62728", "nlos": "#ff7f0e", "reacquisition": "#e6c229", "injected": "#9467bd"}
"""Shading and highlight colour of each GPS-degradation window kind."""
MAP_WINDOWS = ("blackout", "nlos", "injected")
"""Window kinds highlighted on the map (re-acquisition follows every blackout and would hide it)."""
QUALITY_STYLE = {
    1: ("GPS fix: measured", "#4d4d4d"),
    2: ("GPS fix: measured, SBAS/DGPS", "#4d4d4d"),
    4: ("GPS fix: RTK fixed", "#252525"),
    5: ("GPS fix: RTK float", "#969696"),
    6: ("GPS fix: dead reckoning", "#a6761d"),
}
"""GGA quality -> legend label and colour of its fixes (measured ones in greys)."""
TRACK_COLOURS = ("#1f77b4", "#2ca02c", "#9467bd", "#17becf", "#e377c2", "#393b79", "#637939", "#7b4173", "#6baed6", "#31a354")
"""Estimate and odometry colours: none of them a window colour, an outcome colour or a GPS-fix grey."""
FAULT_M = 5.0
"""A measured fix whose true error exceeds this is faulty (as in scenarios.score.metrics)."""
FILE_MODE = 0o644
"""Mode of the written files (atomic_path's temporary files are private, 0600)."""
WIDTH_IN = 11.0
DPI = 100
PLOTS = {
    "map": "The stretch over the world's parts projected onto the water plane (banks, walls and quays, bridges, piers, buildings; trees left "
    "out): true track, GPS fixes, each estimate and matcher odometry; blackout, NLOS and injected-fault stretches highlighted.",
    "error": "Horizontal error against time: each estimator (lines) and each GPS fix (dots); GPS-degradation windows shaded.",
    "hdop_error": "HDOP against the true horizontal error of each measured fix, fixes that used a reflected (NLOS) signal in orange: "
    "an HDOP threshold only helps where the faulty fixes (above the dotted line) sit at high HDOP.",
    "yaw": "Yaw error (estimate minus truth, wrapped to ±180°) against time; windows shaded.",
    "stanford": "Stanford diagram per estimator: each scan's horizontal error against the protection level the estimator reported "
    "for it (fusion.integrity), coloured by epochs per cell; above the diagonal the level failed to bound the error (misleading "
    "information), beyond the dashed alert limit on the error axis while the level was inside it, hazardously.",
    "matchers": "Scan matchers: points per scan (top), the wall-clock time of each registration, a running median over about a second "
    "(middle), and each registration's outcome (bottom, one row per matcher); GPS-degradation windows shaded.",
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
    world: list[world_map.Footprint] = field(default_factory=list)
    alert_limit_m: float = 10.0


def load(
    run_dir: Path, estimator_ids: list[str], matcher_ids: list[str], hdop_limits: dict[str, float], world=None, alert_limit_m: float = 10.0
) -> RunSeries:
    """Read the trajectories, gps.csv, scans.csv and windows.csv of a run directory; with its `world`, the parts under the map."""
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
        world=world_map.footprints(world, overview_extent(truth)) if world is not None and len(truth.t) else [],
        alert_limit_m=alert_limit_m,
    )


def read_tum(path: Path) -> Track:
    """A TUM file as a planar Track on the scenario's clock (empty when the file is missing or has no rows)."""
    rows = files.read_tum(path, scenario_time=True) if path.exists() else np.zeros((0, 8))
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
    return np.degrees(wrap_angle(d))


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
    drawers = {
        "map": map_figure,
        "error": error_figure,
        "hdop_error": hdop_figure,
        "yaw": yaw_figure,
        "stanford": stanford_figure,
        "matchers": matchers_figure,
    }
    written = {}
    for stem, draw in drawers.items():
        figure = draw(series)
        if figure is None:
            continue
        with atomic_path(plots_dir / f"{stem}.png") as tmp:
            figure.savefig(tmp, format="png", dpi=DPI)
            tmp.chmod(FILE_MODE)
        written[f"plots/{stem}.png"] = PLOTS[stem]
    return written


def _figure(height_in: float, rows: int = 1, **grid) -> tuple[Figure, list]:
    """A figure of the report's width with `rows` stacked axes sharing x."""
    figure = Figure(figsize=(WIDTH_IN, height_in), layout="constrained")
    axes = figure.subplots(rows, 1, sharex=rows > 1, squeeze=False, **grid)[:, 0]
    return figure, list(axes)


@dataclass(frozen=True)
class Closeup:
    """The map's close-up: a window, the moment in it of the largest estimator error, and the frame around it."""

    window: Window
    stamp: float
    extent: tuple[float, float, float, float]


def map_figure(series: RunSeries) -> Figure | None:
    """Top view of the stretch and a close-up of the window where an estimate strayed furthest:
    side by side, or stacked when the stretch is much wider than tall."""
    truth = series.truth
    if not len(truth.t):
        return None
    overview = overview_extent(truth)
    aspect = _aspect(overview)
    closeup = _closeup(series)
    if closeup is None:
        figure = Figure(figsize=(WIDTH_IN, float(np.clip(0.8 * WIDTH_IN * aspect, 3.0, 9.0)) + 1.0), layout="constrained")
        axes = [figure.subplots()]
    elif aspect < 0.6:
        figure = Figure(figsize=(WIDTH_IN, 0.85 * WIDTH_IN * (aspect + 0.45) + 1.6), layout="constrained")
        axes = list(figure.subplots(2, 1, height_ratios=[aspect, 0.45]))
        closeup = replace(closeup, extent=_fit_aspect(closeup.extent, 0.45, 0.45))
    else:
        figure = Figure(figsize=(WIDTH_IN, 0.45 * WIDTH_IN * aspect + 1.6), layout="constrained")
        axes = list(figure.subplots(1, 2))
        closeup = replace(closeup, extent=_fit_aspect(closeup.extent, aspect, aspect))
    world = _draw_map(axes[0], series, overview)
    axes[0].set_title("The stretch", fontsize=10)
    if closeup:
        x0, x1, y0, y1 = closeup.extent
        axes[0].add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, ec="black", lw=0.8, ls="--"))
        _draw_map(axes[1], series, closeup.extent)
        _mark_moment(axes[1], series, closeup.stamp)
        axes[1].set_title(
            f"Close-up (dashed box): {closeup.window.kind} {closeup.window.start - series.t0:.0f}–{closeup.window.end - series.t0:.0f} s\n"
            f"markers: where each estimate was at {closeup.stamp - series.t0:.1f} s (star: truth)",
            fontsize=10,
        )
    handles, labels = axes[-1].get_legend_handles_labels()
    handles, labels = handles + world, labels + [str(p.get_label()) for p in world]
    legend = figure.legend(handles, labels, loc="outside lower center", ncol=min(5, len(labels)), fontsize=8)
    for handle in legend.legend_handles:
        if isinstance(handle, PathCollection):
            handle.set_sizes([25])
    return figure


def overview_extent(truth: Track) -> tuple[float, float, float, float]:
    """The map's overview frame: the true track, padded, its height/width ratio in [0.25, 1.2]."""
    return _fit_aspect(_extent(truth.x, truth.y, pad=max(20.0, 0.05 * max(np.ptp(truth.x), np.ptp(truth.y)))), 0.25, 1.2)


def _extent(x: np.ndarray, y: np.ndarray, pad: float) -> tuple[float, float, float, float]:
    """(xmin, xmax, ymin, ymax) around the points, padded."""
    return float(x.min() - pad), float(x.max() + pad), float(y.min() - pad), float(y.max() + pad)


def _aspect(extent: tuple[float, float, float, float]) -> float:
    """Height over width of an extent."""
    return (extent[3] - extent[2]) / (extent[1] - extent[0])


def _fit_aspect(extent: tuple[float, float, float, float], low: float, high: float) -> tuple[float, float, float, float]:
    """The extent grown about its centre along one axis until its height/width ratio lies in [low, high]."""
    x0, x1, y0, y1 = extent
    width, height = x1 - x0, y1 - y0
    if height < low * width:
        grow = (low * width - height) / 2
        return x0, x1, y0 - grow, y1 + grow
    if height > high * width:
        grow = (height / high - width) / 2
        return x0 - grow, x1 + grow, y0, y1
    return extent


def _closeup(series: RunSeries) -> Closeup | None:
    """The close-up on the map window (blackout, NLOS, injected) with the largest estimator error."""
    truth, best = series.truth, None
    errors = [(track.t, horizontal_error(track, truth)) for track in series.estimates.values()]
    for window in (w for w in series.windows if w.kind in MAP_WINDOWS):
        for t, error in errors:
            inside = (t >= window.start) & (t <= window.end)
            if inside.any() and (best is None or error[inside].max() > best[2]):
                best = (window, float(t[inside][np.argmax(error[inside])]), float(error[inside].max()))
    if best is None:
        return None
    window, stamp, worst = best
    margin = 0.25 * (window.end - window.start)
    near = (truth.t >= window.start - margin) & (truth.t <= window.end + margin)
    return Closeup(window, stamp, _extent(truth.x[near], truth.y[near], pad=float(np.clip(1.2 * worst, 10.0, 60.0))))


def _mark_moment(ax, series: RunSeries, stamp: float) -> None:
    """Where the truth and each estimate were at `stamp`, joined by thin lines (along-track errors show too)."""
    truth, palette = series.truth, colours(series)
    i = truth_index(truth, np.array([stamp]))[0]
    for name, track in series.estimates.items():
        j = np.flatnonzero(np.isclose(track.t, truth.t[i], atol=1e-3))
        if len(j):
            ax.plot([truth.x[i], track.x[j[0]]], [truth.y[i], track.y[j[0]]], color=palette[name], lw=0.8, ls=":", zorder=6)
            ax.plot(track.x[j[0]], track.y[j[0]], marker="o", ms=7, color=palette[name], mec="black", mew=0.8, ls="none", zorder=7)
    ax.plot(truth.x[i], truth.y[i], marker="*", ms=12, color="black", ls="none", zorder=7)


def _draw_map(ax, series: RunSeries, extent: tuple[float, float, float, float]) -> list[Patch]:
    """The world's parts, truth, GPS fixes by quality, window highlights, estimates and odometry on one map axis, framed
    to `extent`; returns the legend patches of the world's parts."""
    truth, palette = series.truth, colours(series)
    world = world_map.draw(ax, series.world)
    ax.plot(truth.x, truth.y, color="black", lw=1.6, label="truth", zorder=3)
    for kind in MAP_WINDOWS:
        _highlight_windows(ax, series, kind)
    for name, track in series.estimates.items():
        ax.plot(track.x, track.y, color=palette[name], lw=1.1, label=name, zorder=4)
    for name, track in series.matchers.items():
        ax.plot(track.x, track.y, color=palette[name], lw=1.0, ls="--", label=f"{name} (odometry)", zorder=4)
    quality = series.gps.get("quality", np.zeros(0))
    for q, (label, colour) in QUALITY_STYLE.items():
        keep = quality == q
        if keep.any():
            ax.scatter(series.gps["e"][keep], series.gps["n"][keep], s=5, color=colour, alpha=0.6, lw=0, label=label, zorder=5)
    ax.plot(truth.x[0], truth.y[0], marker="o", ms=9, mfc="white", mec="black", mew=2, ls="none", label="start", zorder=6)
    ax.plot(truth.x[-1], truth.y[-1], marker="s", ms=7, color="black", ls="none", label="end", zorder=6)
    ax.set_xlim(extent[0], extent[1])
    ax.set_ylim(extent[2], extent[3])
    ax.set_aspect("equal", adjustable="box")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.grid(alpha=0.3)
    return world


def _highlight_windows(ax, series: RunSeries, kind: str) -> None:
    """Overlay the true track inside each window of `kind` as a thick translucent line (one legend entry)."""
    truth = series.truth
    label = f"{kind} (truth inside)"
    for window in (w for w in series.windows if w.kind == kind):
        inside = (truth.t >= window.start) & (truth.t <= window.end)
        ax.plot(truth.x[inside], truth.y[inside], color=WINDOW_COLOURS[kind], lw=7, alpha=0.5, solid_capstyle="butt", label=label, zorder=2.5)
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
    """An axis limit that keeps one divergent series from flattening the rest: 1.2 x the 99th percentile,
    or just above the largest value when that is at most half as high again."""
    finite = np.concatenate([np.asarray(v)[np.isfinite(v)] for v in values]) if values else np.zeros(0)
    if not len(finite):
        return floor
    limit, peak = 1.2 * float(np.percentile(finite, 99)), float(finite.max())
    return max(floor, 1.05 * peak if peak <= 1.5 * limit else limit)


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
    for q, (label, colour) in QUALITY_STYLE.items():
        keep = series.gps.get("quality", np.zeros(0)) == q
        if keep.any():
            ax.scatter(series.gps["t"][keep] - series.t0, fix_error[keep], s=4, color=colour, alpha=0.6, lw=0, zorder=4)
            handles.append(Line2D([], [], marker="o", ls="none", color=colour, ms=4, label=label))
    for name, error in errors.items():
        handles += ax.plot(series.estimates[name].t - series.t0, error, color=palette[name], lw=1.2, label=name, zorder=3)
    top = clip_limit([*errors.values(), fix_error], floor=FAULT_M * 1.2)
    ax.set_ylim(0, top)
    handles.append(ax.axhline(FAULT_M, color="black", lw=0.8, ls=":", label=f"{FAULT_M:g} m (faulty fix)"))
    clipped = [f"{n} {np.nanmax(e):.0f} m" for n, e in errors.items() if len(e) and np.nanmax(e) > top]
    ax.set_title(
        "Horizontal error of each estimate and (dots) of each GPS fix"
        + (f" (axis clipped at {top:.0f} m; peaks: {', '.join(clipped)})" if clipped else ""),
        fontsize=10,
    )
    ax.set_xlabel("time since start (s)")
    ax.set_ylabel("horizontal error (m)")
    ax.grid(alpha=0.3)
    ax.legend(handles=[*handles, *patches], loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    return figure


def stanford_figure(series: RunSeries) -> Figure | None:
    """Error against protection level for each estimator whose scans.csv column holds levels (scenarios.report.stanford)."""
    epochs = {name: e for name in series.estimates if (e := stanford_epochs(series, name)) is not None}
    return stanford.figure(epochs, series.alert_limit_m, "Protection levels", WIDTH_IN)


def stanford_epochs(series: RunSeries, name: str) -> stanford.Epochs | None:
    """An estimator's (error, protection level) per scan with both, or None when scans.csv has no level column for it."""
    level, track, scan_t = series.scans.get(f"{name}.hpl"), series.estimates.get(name), series.scans.get("t", np.zeros(0))
    if level is None or track is None or not len(track.t) or not len(scan_t):
        return None
    # the TUM file holds the scans with an estimate; scans.csv every scan: the level at each pose's scan
    at = np.rint(np.interp(track.t, scan_t, np.arange(len(scan_t)))).astype(int)  # nearest scan (scans.csv's t has 1 ms)
    return stanford.Epochs.of(horizontal_error(track, series.truth), np.where(np.abs(scan_t[at] - track.t) < 1e-3, level[at], np.nan))


def hdop_figure(series: RunSeries) -> Figure | None:
    """Scatter of HDOP against the true horizontal error of measured fixes, NLOS fixes in another colour."""
    gps = series.gps
    if "hdop" not in gps:
        return None
    measured = np.isin(gps["quality"], sorted(POSITION_QUALITIES)) & np.isfinite(gps["hdop"]) & np.isfinite(gps["err_h"])
    if not measured.any():
        return None
    nlos = measured & (gps["nlos_used"] == 1)
    clear = measured & ~nlos
    figure, (ax,) = _figure(4.8)
    for keep, size, colour, label in ((clear, 9, "#1f77b4", "direct signals only"), (nlos, 14, WINDOW_COLOURS["nlos"], "uses an NLOS signal")):
        if keep.any():
            ax.scatter(gps["hdop"][keep], gps["err_h"][keep], s=size, color=colour, alpha=0.6, lw=0, label=f"{label} ({keep.sum()} fixes)")
    ax.axhline(FAULT_M, color="black", lw=0.8, ls=":", label=f"fault threshold {FAULT_M:g} m")
    for name, limit in series.hdop_limits.items():
        ax.axvline(limit, color="#d62728", lw=0.9, ls="--", label=f"{name}: trusts HDOP ≤ {limit:g}")
    r = correlation(gps["hdop"][measured], gps["err_h"][measured])
    ax.set_title(
        "HDOP against true horizontal error of measured fixes" + (f" (correlation r = {round(r, 2) + 0.0:.2f})" if math.isfinite(r) else ""),
        fontsize=10,
    )
    ax.set_xlabel("HDOP (dimensionless)")
    ax.set_ylabel("true horizontal error (m)")
    ax.set_ylim(0, clip_limit([gps["err_h"][measured]], floor=FAULT_M * 1.2))
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    return figure


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson correlation of a and b (NaN when either does not vary)."""
    if len(a) < 3 or np.std(a) == 0 or np.std(b) == 0:
        return math.nan
    return float(np.corrcoef(a, b)[0, 1])


def yaw_figure(series: RunSeries) -> Figure | None:
    """Signed yaw error of every estimator and matcher against time, windows shaded."""
    lines = [(name, track, "-", name) for name, track in series.estimates.items()]
    lines += [(name, track, "--", f"{name} (odometry)") for name, track in series.matchers.items()]
    if not lines:
        return None
    figure, (ax,) = _figure(4.8)
    patches = shade_windows(ax, series)
    palette = colours(series)
    errors = []
    handles = []
    for name, track, style, label in lines:
        errors.append(yaw_error_deg(track, series.truth))
        handles += ax.plot(track.t - series.t0, errors[-1], color=palette[name], lw=1.1, ls=style, label=label)
    top = clip_limit([np.abs(e) for e in errors], floor=2.0)
    ax.set_ylim(-top, top)
    ax.axhline(0, color="black", lw=0.6)
    ax.set_title(f"Yaw error (axis ±{top:.1f}°)", fontsize=10)
    ax.set_xlabel("time since start (s)")
    ax.set_ylabel("yaw error (deg)")
    ax.grid(alpha=0.3)
    ax.legend(handles=[*handles, *patches], loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    return figure


SMOOTH_SCANS = 11
"""Registration times are drawn as their running median over this many scans (about a second): wall clock is noisy."""
LINE_STYLES = ("-", "--", ":", "-.")
"""Dash patterns cycled over the matchers, so overlapping lines stay apart by more than their colour."""


def matchers_figure(series: RunSeries) -> Figure | None:
    """Small multiples over time: points per scan (one line when every matcher saw the same scans), each matcher's
    registration time, and each registration's outcome (one strip row per matcher)."""
    mids = [m for m in series.matchers if f"{m}.ok" in series.scans]
    if not mids or not len(series.scans["t"]):
        return None
    figure, (points_ax, time_ax, strip) = _figure(6.6, rows=3, height_ratios=[2.2, 2.2, 0.4 + 0.35 * len(mids)])
    figure.suptitle("Scan matchers: points per scan, registration time and outcome", fontsize=10)
    palette = colours(series)
    t = series.scans["t"] - series.t0
    counts = {m: series.scans[f"{m}.points"] for m in mids}
    same = all(np.array_equal(counts[m], counts[mids[0]], equal_nan=True) for m in mids)
    handles = []
    if same:
        label = "every matcher (same scans)" if len(mids) > 1 else mids[0]
        handles += points_ax.plot(t, counts[mids[0]], color="#4d4d4d" if len(mids) > 1 else palette[mids[0]], lw=1.0, label=label)
    else:
        for i, m in enumerate(mids):
            handles += points_ax.plot(t, counts[m], color=palette[m], lw=1.0, ls=LINE_STYLES[i % len(LINE_STYLES)], label=m)
    patches = shade_windows(points_ax, series)
    points_ax.set_ylabel("points per scan (count)")
    points_ax.set_ylim(bottom=0)
    points_ax.grid(alpha=0.3)
    points_ax.legend(handles=[*handles, *patches], loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    shade_windows(time_ax, series)
    for i, m in enumerate(mids):
        ms = np.where(outcome_codes(series.scans, m) >= 0, series.scans[f"{m}.ms"], np.nan)
        ms[series.scans[f"{m}.gated"] == 1] = np.nan  # dropped before registration: no time
        time_ax.plot(t, rolling_median(ms, SMOOTH_SCANS), color=palette[m], lw=1.2, ls=LINE_STYLES[i % len(LINE_STYLES)], label=m)
    time_ax.set_ylabel(f"registration time (ms,\nmedian of {SMOOTH_SCANS} scans)")
    time_ax.set_ylim(bottom=0)
    time_ax.grid(alpha=0.3)
    time_ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    _outcome_strip(strip, series, mids, t)
    return figure


def rolling_median(values: np.ndarray, width: int) -> np.ndarray:
    """The median of the finite values in a centred window of `width` samples (NaN where the window has none)."""
    values = np.asarray(values, dtype=float)
    if len(values) < width:
        return values
    half = width // 2
    padded = np.pad(values, half, constant_values=np.nan)
    windows = np.lib.stride_tricks.sliding_window_view(padded, width)
    out = np.full(len(values), np.nan)
    has = np.isfinite(windows).any(axis=1)
    out[has] = np.nanmedian(windows[has], axis=1)
    return out


OUTCOMES = (("matched", "#2ca02c"), ("degenerate", "#e6c229"), ("gated", "#7f7f7f"), ("failed", "#d62728"))
"""Registration outcomes of the matchers strip, in drawing order."""


def _outcome_strip(ax, series: RunSeries, mids: list[str], t: np.ndarray) -> None:
    """One row per matcher: runs of scans coloured by their outcome (the first scan has no reference)."""
    ends = np.r_[t[1:], t[-1] + (np.median(np.diff(t)) if len(t) > 1 else 0.1)]
    for row, m in enumerate(mids):
        code = outcome_codes(series.scans, m)
        starts = np.r_[0, np.flatnonzero(np.diff(code)) + 1]
        stops = np.r_[starts[1:], len(code)]
        for index, (_name, colour) in enumerate(OUTCOMES):
            spans = [(t[a], ends[b - 1] - t[a]) for a, b in zip(starts, stops) if code[a] == index]
            ax.broken_barh(spans, (row - 0.4, 0.8), facecolor=colour, edgecolor=colour, lw=0.6)
    ax.set_yticks(range(len(mids)), mids)
    ax.set_ylim(len(mids) - 0.5, -0.5)
    ax.set_xlabel("time since start (s)")
    ax.legend(handles=[Patch(color=c, label=n) for n, c in OUTCOMES], loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)


def outcome_codes(scans: dict[str, np.ndarray], m: str) -> np.ndarray:
    """Per scan: its index in OUTCOMES (gated before anything else), -1 for the first scan."""
    ok, gated, degenerate = (scans[f"{m}.{k}"] == 1 for k in ("ok", "gated", "degenerate"))
    code = np.where(gated, 2, np.where(ok, np.where(degenerate, 1, 0), 3))
    code[:1] = -1
    return code
