"""The comparison report's figures over seeds: each component's horizontal error against time through the GPS-degradation
windows (a figure per configuration), and APE per component and configuration with its range over seeds.

What a figure plots is computed apart from its drawing (`error_curves`, `ape_rows`), so tests check the plotted numbers
rather than pixels. Colours and dash patterns follow the component id and are the same in every figure of a report.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch
from matplotlib.ticker import FuncFormatter, LogLocator, NullFormatter

from scenarios.report import plots
from scenarios.report.compare.groups import APE_ALIGNED, APE_P95, Configuration, Spread
from scenarios.report.compare.roc import roc_path
from scenarios.report.compare.runs import RunInfo, plural
from scenarios.report.document import Column
from scenarios.score.anchoring import nearest
from scenarios.score.metrics import align_se2

KINDS = {"estimators": ("estimator", APE_P95), "matchers": ("matcher", APE_ALIGNED)}
"""Per component kind: its name in words and the APE column its figure plots (that of the summary tables)."""
APE_KEY = "ape:"
"""Prefix of an APE figure among the drawn images (then the kind: 'ape:estimators')."""
ERROR_KEY = "error:"
"""Prefix of a configuration's error-against-time figure among the drawn images (then its title)."""
SEED_ALPHA = 0.3
"""Opacity of each seed's own line behind the median over seeds."""
MEDIAN_LW = (1.4, 3.2)
"""Width of the last and the first median line drawn in a panel: each line drawn over wider ones, so one that follows
another exactly still shows as a core inside its outline."""
PANEL_IN, LEGEND_ROW_IN = 3.2, 0.18
"""Height of an error panel, inches, unless its legend (a row per component and window kind) needs more."""
ROW_IN, GROUP_IN = 0.24, 0.3
"""Height of an APE figure's row and of a configuration's heading row, inches."""
LOG_RATIO = 30.0
"""An APE axis is logarithmic when its largest value exceeds its smallest positive one by more than this."""


@dataclass(frozen=True)
class Style:
    """A component's colour and dash pattern."""

    colour: str
    dash: str


def styles(confs: list[Configuration]) -> dict[str, Style]:
    """A style per component id over every configuration (estimators first): colours cycle, then the dash pattern changes."""
    ids = list(dict.fromkeys(cid for kind in KINDS for c in confs for cid in getattr(c, kind)))
    n = len(plots.TRACK_COLOURS)
    return {cid: Style(plots.TRACK_COLOURS[i % n], plots.LINE_STYLES[(i // n) % len(plots.LINE_STYLES)]) for i, cid in enumerate(ids)}


# ---- APE per component and configuration ---------------------------------------------------------------


@dataclass(frozen=True)
class ApeRow:
    """One dot of the APE figure: a component in a configuration, its APE over the seeds it did not fail (None: no value)."""

    component: str
    configuration: str
    spread: Spread | None
    failures: int
    runs: int


def ape_rows(confs: list[Configuration], kind: str) -> list[ApeRow]:
    """A row per component and configuration it ran in, in the configurations' order, each configuration's components
    sorted by median APE (lowest first; those without a value last)."""
    column = KINDS[kind][1]
    rows = []
    for conf in confs:
        nodes = getattr(conf, kind)
        mine = [ApeRow(cid, conf.title, node.get(column.title), node["failures"], node["runs"]) for cid, node in nodes.items()]
        rows += sorted(mine, key=lambda r: (r.spread is None, r.spread.median if r.spread else 0.0))
    return rows


def ape_label(row: ApeRow, column: Column) -> str:
    """The value printed beside a dot: '2.80 (2.60–3.10)', with '1 of 3 failed' or 'no value' when so."""
    s = row.spread
    text = "no value" if s is None else column.fmt(s.median) + (f" ({column.fmt(s.lo)}–{column.fmt(s.hi)})" if s.n > 1 else " (1 seed)")
    return text + (f", {row.failures} of {row.runs} failed" if row.failures else "")


def ape_figure(rows: list[ApeRow], kind: str, palette: dict[str, Style]) -> Figure | None:
    """Horizontal dots at the median with min–max bars, a row per component, grouped under each configuration's title
    (the title omitted when there is one configuration); the value printed on the right. None without any value."""
    word, column = KINDS[kind]
    if not any(r.spread for r in rows):
        return None
    titles = list(dict.fromkeys(r.configuration for r in rows))
    grouped = len(titles) > 1
    figure = Figure(figsize=(plots.WIDTH_IN, 1.2 + ROW_IN * len(rows) + (GROUP_IN * len(titles) if grouped else 0.0)), layout="constrained")
    ax = figure.subplots()
    y, ticks, labels, values = 0.0, [], [], []
    for title in titles:
        if grouped:
            ax.text(0.005, y, title, transform=ax.get_yaxis_transform(), fontsize=9, fontweight="bold", va="center")
            y -= GROUP_IN / ROW_IN
        for r in (r for r in rows if r.configuration == title):
            ticks.append(y)
            labels.append(r.component)
            values.append(ape_label(r, column))
            if r.spread is not None:
                s, style = r.spread, palette[r.component]
                ax.errorbar(s.median, y, xerr=[[s.median - s.lo], [s.hi - s.median]], fmt="o", color=style.colour, ms=6, capsize=3, lw=1.2)
            y -= 1.0
    _ape_axes(ax, rows, ticks, labels, values)
    scale = ", logarithmic axis" if ax.get_xscale() == "log" else ""
    ax.set_xlabel(f"{column.title}: dot at the median over seeds, bar from min to max{scale}")
    ax.set_title(f"{word.capitalize()}s: {column.title.removesuffix(' (m)')} per {word}" + ("" if grouped else f" in {titles[0]}"), fontsize=10)
    return figure


def _ape_axes(ax, rows: list[ApeRow], ticks: list[float], labels: list[str], values: list[str]) -> None:
    """The APE axes' scale (logarithmic over a wide range), rows (component ids left, values right) and limits."""
    finite = [v for r in rows if r.spread for v in (r.spread.lo, r.spread.hi)]
    positive = [v for v in finite if v > 0]
    if positive and max(finite) > LOG_RATIO * min(positive):
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
        ax.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f"{value:g}"))
        ax.xaxis.set_minor_formatter(NullFormatter())
    else:
        ax.set_xlim(left=0, right=1.08 * max(finite) if max(finite) > 0 else 1.0)
    ax.set_yticks(ticks, labels, fontsize=8)
    ax.set_ylim(min(ticks) - 0.7, 0.7)
    right = ax.twinx()
    right.set_ylim(ax.get_ylim())
    right.set_yticks(ticks, values, fontsize=8)
    ax.grid(axis="x", alpha=0.3)


# ---- horizontal error against time -------------------------------------------------------------------


@dataclass(frozen=True)
class Curves:
    """One component's horizontal error over a configuration's seeds on a common time grid (seconds since the first scan of
    the first run holding it): each seed's error (NaN where it had no pose near a grid time) and the median over seeds."""

    t: np.ndarray
    seeds: list[np.ndarray]
    median: np.ndarray


def run_errors(run: RunInfo, truth: plots.Track, kind: str, cid: str) -> tuple[np.ndarray, np.ndarray]:
    """A run's times since its first scan and the component's horizontal error there from its <id>.tum against the run's
    truth; a matcher's after the best-fit planar motion (align_se2), as its aligned APE is measured. Empty when the run has
    no such file or poses."""
    track = plots.read_tum(run.path / f"{cid}.tum")
    if not len(truth.t) or not len(track.t):
        return np.zeros(0), np.zeros(0)
    if kind == "matchers":
        track = _aligned(track, truth)
    return track.t - truth.t[0], plots.horizontal_error(track, truth)


def _aligned(track: plots.Track, truth: plots.Track) -> plots.Track:
    """The track moved by the rigid planar motion that best fits its positions to the truth's at the same times."""
    i = plots.truth_index(truth, track.t)
    estimate, reference = np.tile(np.eye(4), (len(track.t), 1, 1)), np.tile(np.eye(4), (len(track.t), 1, 1))
    estimate[:, 0, 3], estimate[:, 1, 3] = track.x, track.y
    reference[:, 0, 3], reference[:, 1, 3] = truth.x[i], truth.y[i]
    moved = align_se2(estimate, reference)
    return plots.Track(track.t, moved[:, 0, 3], moved[:, 1, 3], track.yaw)


def on_grid(t: np.ndarray, values: np.ndarray, grid: np.ndarray) -> np.ndarray:
    """The value stamped nearest each grid time within half the grid's median step, NaN where there is none."""
    out = np.full(len(grid), np.nan)
    if not len(t) or not len(grid):
        return out
    tolerance = 0.5 * float(np.median(np.diff(grid))) if len(grid) > 1 else np.inf
    index, hit = nearest(t, grid, tolerance)
    out[hit] = values[index[hit]]
    return out


def error_curves(conf: Configuration, kind: str) -> dict[str, Curves]:
    """Each component's error curves over the configuration's runs (those whose runs hold no poses left out)."""
    truths = {run.path: plots.read_tum(run.path / "groundtruth.tum") for run in conf.runs}
    out = {}
    for cid in getattr(conf, kind):
        series = [run_errors(run, truths[run.path], kind, cid) for run in conf.runs if cid in (run.metrics.get(kind) or {})]
        series = [(t, e) for t, e in series if len(t)]
        if not series:
            continue
        grid = series[0][0]
        seeds = [on_grid(t, e, grid) for t, e in series]
        with warnings.catch_warnings():  # a grid time no seed has a pose at: NaN, as meant
            warnings.simplefilter("ignore", RuntimeWarning)
            median = np.nanmedian(np.vstack(seeds), axis=0)
        out[cid] = Curves(grid, seeds, median)
    return out


def merged_windows(conf: Configuration) -> list[plots.Window]:
    """The GPS-degradation windows of any of the configuration's runs (windows.csv), on each run's time since its first
    scan, overlapping ones of a kind merged."""
    spans: dict[str, list[tuple[float, float]]] = {}
    for run in conf.runs:
        truth = plots.read_tum(run.path / "groundtruth.tum")
        rows = plots.read_csv(run.path / "windows.csv")
        t0 = float(truth.t[0]) if len(truth.t) else 0.0
        for kind, start, end in zip(rows.get("kind", []), rows.get("start", []), rows.get("end", [])):
            spans.setdefault(str(kind), []).append((float(start) - t0, float(end) - t0))
    out = []
    for kind, pairs in spans.items():
        for start, end in sorted(pairs):
            if out and out[-1].kind == kind and start <= out[-1].end:
                out[-1] = plots.Window(kind, out[-1].start, max(out[-1].end, end))
            else:
                out.append(plots.Window(kind, start, end))
    return out


def error_figure(conf: Configuration, palette: dict[str, Style]) -> Figure | None:
    """A panel per component kind with curves (estimators above matchers, shared time axis): the median over seeds as a
    line, each seed faintly behind it, the windows shaded. None when no component has poses."""
    panels = {kind: curves for kind in KINDS if (curves := error_curves(conf, kind))}
    if not panels:
        return None
    windows = merged_windows(conf)
    entries = [len(curves) + len({w.kind for w in windows}) for curves in panels.values()]  # legend rows per panel
    heights = [max(PANEL_IN, 0.6 + LEGEND_ROW_IN * n) for n in entries]
    figure = Figure(figsize=(plots.WIDTH_IN, 0.6 + sum(heights)), layout="constrained")
    axes = figure.subplots(len(panels), 1, sharex=True, squeeze=False, height_ratios=heights)[:, 0]
    seeds = len(conf.runs)
    for ax, (kind, curves) in zip(axes, panels.items()):
        patches = shade(ax, windows)
        widths = np.linspace(MEDIAN_LW[1], MEDIAN_LW[0], len(curves)) if len(curves) > 1 else [MEDIAN_LW[0]]
        handles = [_draw_curves(ax, _curve_label(cid, c, seeds), c, palette[cid], w) for (cid, c), w in zip(curves.items(), widths)]
        top = plots.clip_limit([v for c in curves.values() for v in c.seeds], floor=1.0)
        ax.set_ylim(0, top)
        peaks = [f"{cid} {np.nanmax(np.vstack(c.seeds)):.0f} m" for cid, c in curves.items() if np.nanmax(np.vstack(c.seeds)) > top]
        word = KINDS[kind][0]
        what = f"{word}s' odometry after the best-fit planar motion" if kind == "matchers" else f"{word}s"
        ax.set_title(
            f"{what.capitalize()}: horizontal error, "
            + ("line: median over seeds, thin: each seed" if seeds > 1 else "one seed")
            + (f" (axis clipped at {top:.0f} m; peaks: {', '.join(peaks)})" if peaks else ""),
            fontsize=10,
        )
        ax.set_ylabel("horizontal error (m)")
        ax.grid(alpha=0.3)
        ax.legend(handles=[*handles, *patches], loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize=8)
    axes[-1].set_xlabel("time since the first scan (s)")
    shaded = "GPS-degradation windows of any run shaded" if windows else "no GPS-degradation window in any run"
    figure.suptitle(f"{conf.title}: {plural(seeds, 'run')}, {shaded}", fontsize=10)
    return figure


def shade(ax, windows: list[plots.Window]) -> list[Patch]:
    """Shade the windows on a time axis in the run report's colours; returns a legend patch per kind present."""
    for window in windows:
        ax.axvspan(window.start, window.end, color=plots.WINDOW_COLOURS.get(window.kind, "grey"), alpha=0.15, lw=0)
    kinds = dict.fromkeys(w.kind for w in windows)
    return [Patch(color=plots.WINDOW_COLOURS.get(k, "grey"), alpha=0.3, label=k) for k in kinds]


def _curve_label(cid: str, curves: Curves, runs: int) -> str:
    """The component id, with how many of the configuration's runs hold its poses when not all do."""
    return cid if len(curves.seeds) == runs else f"{cid} ({len(curves.seeds)} of {plural(runs, 'run')})"


def _draw_curves(ax, label: str, curves: Curves, style: Style, width: float) -> Line2D:
    """Each seed's line faintly (with more than one) and the median over seeds, labelled; returns the median's line."""
    if len(curves.seeds) > 1:
        for values in curves.seeds:
            ax.plot(curves.t, values, color=style.colour, ls=style.dash, lw=0.7, alpha=SEED_ALPHA)
    (line,) = ax.plot(curves.t, curves.median, color=style.colour, ls=style.dash, lw=width, label=label)
    return line


# ---- drawing into the report --------------------------------------------------------------------------


def draw(confs: list[Configuration], out_dir: Path) -> dict[str, str]:
    """Draw the APE figures (one per component kind) and each configuration's error-against-time figure where there is
    data; returns {key: path relative to out_dir} (APE_KEY + kind, ERROR_KEY + configuration title)."""
    palette = styles(confs)
    figures: dict[str, tuple[str, Figure | None]] = {
        APE_KEY + kind: (f"plots/ape-{kind}.png", ape_figure(ape_rows(confs, kind), kind, palette)) for kind in KINDS
    }
    for index, conf in enumerate(confs):
        figures[ERROR_KEY + conf.title] = (roc_path(index, conf.title).replace("plots/roc-", "plots/error-"), error_figure(conf, palette))
    written = {}
    for key, (path, figure) in figures.items():
        if figure is None:
            continue
        (out_dir / path).parent.mkdir(parents=True, exist_ok=True)
        figure.savefig(out_dir / path, format="png", dpi=plots.DPI)
        written[key] = path
    return written
