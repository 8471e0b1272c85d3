"""The monitors' ROC over a configuration's pooled measured fixes, and its figure."""

from __future__ import annotations

import re
import textwrap
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import PercentFormatter

from fusion.observation import POSITION_QUALITIES
from scenarios.report import document, plots
from scenarios.report.compare.runs import RunInfo, plural
from scenarios.score.metrics import FAULT_M, roc

ZOOM_FA = 0.1
"""The right-hand ROC panel shows false-alarm rates up to this."""


@dataclass(frozen=True)
class RocCurve:
    """One estimator's monitor over a configuration's pooled measured fixes: its ROC and the operating point of its verdicts."""

    eid: str
    monitor: str
    false_alarm: np.ndarray
    recall: np.ndarray
    operating: tuple[float, float]


@dataclass(frozen=True)
class Roc:
    """A configuration's pooled measured fixes: how many, how many faulty, and each monitor's curve."""

    measured: int
    faulty: int
    curves: list[RocCurve]


def read_gps(run: RunInfo, eids: list[str]) -> dict[str, np.ndarray]:
    """gps.csv's quality, added error and each estimator's verdict and statistic as floats (empty without the file)."""
    path = run.path / "gps.csv"
    table = plots.read_csv(path)
    if "quality" not in table or "added_err_h" not in table:
        return {}
    n = len(table["quality"])
    wanted = {
        "quality": table["quality"],
        "added_err_h": table["added_err_h"],
        **{f"{e}.{k}": table.get(f"{e}.{k}", np.full(n, fill)) for e in eids for k, fill in (("trusted", 1.0), ("statistic", np.nan))},
    }
    bad = [name for name, column in wanted.items() if column.dtype.kind != "f"]
    if bad:
        raise ValueError(f"{path}: column {bad[0]} holds something other than numbers")
    return wanted


def monitor_roc(runs: list[RunInfo], eids: list[str], monitors: dict[str, str]) -> Roc:
    """The ROC of each estimator with a monitor over the measured fixes of all runs, pooled (faulty: > 5 m added by the environment)."""
    tables = [t for t in (read_gps(r, eids) for r in runs) if t]
    measured = [np.isin(t["quality"], sorted(POSITION_QUALITIES)) for t in tables]
    faulty = np.concatenate([t["added_err_h"][m] > FAULT_M for t, m in zip(tables, measured)]) if tables else np.zeros(0, bool)
    curves = []
    for eid in (e for e in eids if monitors.get(e, "none") != "none"):
        statistic = np.concatenate([t[f"{eid}.statistic"][m] for t, m in zip(tables, measured)]) if tables else np.zeros(0)
        if not faulty.any() or not np.isfinite(statistic).any():
            continue
        flagged = np.concatenate([t[f"{eid}.trusted"][m] == 0 for t, m in zip(tables, measured)])
        false_alarm, recall, _ = roc(statistic, faulty)
        clean = ~faulty
        operating = (float((flagged & clean).sum() / clean.sum()) if clean.any() else float("nan"), float((flagged & faulty).sum() / faulty.sum()))
        curves.append(RocCurve(eid, monitors[eid], false_alarm, recall, operating))
    return Roc(len(faulty), int(faulty.sum()), curves)


def roc_path(index: int, title: str) -> str:
    """The ROC figure's path relative to the report: numbered (unique) and named after the configuration's title."""
    return f"plots/roc-{index:02d}-{re.sub(r'[^A-Za-z0-9_.=-]+', '_', title).strip('_')[:60]}.png"


def roc_figure(title: str, pooled: Roc, eids: list[str], n_runs: int) -> Figure:
    """Recall against false-alarm rate of each monitor, its verdicts as a dot: whole range (left), the first 10 % of false alarms (right).

    `title` names the configuration, `eids` are all its estimators (their colours), `n_runs` how many runs were pooled.
    """
    figure = Figure(figsize=(plots.WIDTH_IN, 5.2), layout="constrained")
    axes = figure.subplots(1, 2)
    palette = {eid: plots.TRACK_COLOURS[i % len(plots.TRACK_COLOURS)] for i, eid in enumerate(eids)}
    handles = []
    for curve in pooled.curves:
        fa, recall = curve.operating
        label = (
            f"{curve.eid} (monitor {curve.monitor}): its verdicts flag {document.share(recall)} of faulty fixes at {document.share(fa)} false alarms"
        )
        for ax in axes:
            (line,) = ax.plot(curve.false_alarm, curve.recall, color=palette[curve.eid], lw=1.5, label=label)
            ax.plot(fa, recall, marker="o", ms=8, color=palette[curve.eid], mec="black", mew=0.8, ls="none", zorder=5)
        handles.append(line)
    axes[0].plot([0, 1], [0, 1], color="grey", lw=0.8, ls=":")
    handles += [
        Line2D([], [], marker="o", ls="none", mfc="white", mec="black", ms=8, label="dot: the operating point of its actual verdicts"),
        Line2D([], [], color="grey", lw=0.8, ls=":", label="chance"),
    ]
    for ax, right, panel in zip(axes, (1.0, ZOOM_FA), ("whole range", f"false-alarm rates up to {ZOOM_FA:.0%}")):
        ax.set_xlim(0, right)
        ax.set_ylim(0, 1.02)
        ax.xaxis.set_major_formatter(PercentFormatter(1.0, decimals=0))
        ax.yaxis.set_major_formatter(PercentFormatter(1.0, decimals=0))
        ax.set_xlabel("false-alarm rate (clean measured fixes flagged)")
        ax.set_title(panel, fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("recall (faulty fixes flagged)")
    figure.suptitle(
        textwrap.fill(f"{title}: {pooled.faulty} faulty of {pooled.measured} measured fixes over {plural(n_runs, 'run')}", 130), fontsize=11
    )
    figure.legend(handles=handles, loc="outside lower center", ncol=1, fontsize=8)
    return figure
