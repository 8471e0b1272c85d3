"""Plots of a sweep: metrics against a swept parameter, a line per metric (and per combination of the
other swept parameters and scenario), the median over seeds with the min-max band and each seed's dot."""

from __future__ import annotations

import json
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from riverbench.atomic import atomic_path
from scenarios.batch.table import PARAM_PREFIX
from scenarios.report.plots import DPI, FILE_MODE, TRACK_COLOURS
from scenarios.score import units

MAX_LINES = 10
"""Lines on one figure; more combinations than this are left out (and the title says how many)."""


@dataclass(frozen=True)
class Line:
    """One line of a figure: its label and, per x, the values over seeds."""

    label: str
    x: list
    values: list[list[float]]


def default_metrics(rows: list[dict]) -> list[list[str]]:
    """The figures drawn when no metric is named: every estimator's APE p95; every matcher's success; every command
    (or scored-in) matcher's coverage, the share of scans it gave a pose, its success's counterpart."""
    names = [k for r in rows for k in r]
    groups = [r"estimators\.[^.]+\.ape\.p95", r"matchers\.[^.]+\.success", r"matchers\.[^.]+\.coverage"]
    return [group for pattern in groups if (group := list(dict.fromkeys(k for k in names if re.fullmatch(pattern, k))))]


def lines(rows: list[dict], metrics: list[str], param: str) -> list[Line]:
    """Per metric, scenario and combination of the other swept parameters: values over seeds at each x."""
    key = PARAM_PREFIX + param
    others = sorted({k for r in rows for k in r if k.startswith(PARAM_PREFIX) and k != key})
    scenarios = {r["scenario"] for r in rows}
    groups: dict[str, dict] = {}
    for r in rows:
        if r["status"] != "ok" or r.get(key) is None:
            continue
        context = [r["scenario"]] if len(scenarios) > 1 else []
        context += [f"{k.removeprefix(PARAM_PREFIX)}={_short(r.get(k))}" for k in others]
        for metric in metrics:
            value = r.get(metric)
            if value is None or value != value:
                continue
            label = ", ".join([_metric_label(metric, metrics)] * (len(metrics) > 1) + context) or _metric_label(metric, metrics)
            groups.setdefault(label, {}).setdefault(_hashable(r[key]), []).append(float(value))
    return [Line(label, list(by_x), list(by_x.values())) for label, by_x in groups.items()]


def figure(rows: list[dict], metrics: list[str], param: str, log_x: bool = False) -> Figure | None:
    """The metrics against `param`: median over seeds (line), min-max (band), every seed (dots); None without data."""
    drawn = lines(rows, metrics, param)
    if not drawn:
        return None
    numeric = all(isinstance(x, (int, float)) and not isinstance(x, bool) for line in drawn for x in line.x)
    categories = list(dict.fromkeys(x for line in drawn for x in line.x))
    fig = Figure(figsize=(8.0, 4.6), layout="constrained")
    ax = fig.subplots()
    for i, line in enumerate(drawn[:MAX_LINES]):
        order = np.argsort(line.x) if numeric else np.argsort([categories.index(x) for x in line.x])
        x = np.array([line.x[j] if numeric else categories.index(line.x[j]) for j in order], dtype=float)
        values = [line.values[j] for j in order]
        colour = TRACK_COLOURS[i % len(TRACK_COLOURS)]
        ax.plot(x, [np.median(v) for v in values], "-o", color=colour, label=line.label, lw=1.6, ms=4)
        if any(len(v) > 1 for v in values):
            ax.fill_between(x, [min(v) for v in values], [max(v) for v in values], color=colour, alpha=0.15, lw=0)
        for xi, v in zip(x, values):
            ax.plot(np.full(len(v), xi), v, ".", color=colour, alpha=0.5, ms=4)
    if not numeric:
        ax.set_xticks(range(len(categories)), [_short(c) for c in categories])
    elif log_x:
        ax.set_xscale("log")
    seeds = max(len(v) for line in drawn for v in line.values)
    ax.set_xlabel(param)
    quantities = {units.quantity_of(m) for m in metrics}
    unit = f" ({quantities.pop().unit})" if len(quantities) == 1 and None not in quantities else ""
    ax.set_ylabel((metrics[0] if len(metrics) == 1 else _common_suffix(metrics)) + unit)
    hidden = f" ({len(drawn) - MAX_LINES} more lines not drawn)" if len(drawn) > MAX_LINES else ""
    names = sorted({r["scenario"] for r in rows if r["status"] == "ok"})
    where = f"{names[0]}: " if len(names) == 1 else ""
    ax.set_title(f"{where}median over {seeds} seed{'s' * (seeds > 1)}, band: min to max{hidden}", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    return fig


def write(out_dir: Path, rows: list[dict], params: list[str], metric_groups: list[list[str]], log_params: set[str]) -> list[Path]:
    """plots/<metrics>--<param>.png for each group of metrics and swept parameter; returns the files written."""
    written = []
    for metrics in metric_groups:
        for param in params:
            fig = figure(rows, metrics, param, log_x=param in log_params)
            if fig is None:
                continue
            stem = _slug(metrics[0] if len(metrics) == 1 else _group_name(metrics))
            path = Path(out_dir) / "plots" / f"{stem}--{_slug(param)}.png"
            with atomic_path(path) as tmp:
                fig.savefig(tmp, format="png", dpi=DPI)
                tmp.chmod(FILE_MODE)
            written.append(path)
    return written


def _metric_label(metric: str, metrics: list[str]) -> str:
    """The part of a metric's name that differs within its group (the id): 'ekf' of 'estimators.ekf.ape.p95'."""
    if len(metrics) == 1:
        return metric
    parts = metric.split(".")
    return parts[1] if len(parts) > 2 else metric


def _common_suffix(metrics: list[str]) -> str:
    """'estimators.*.ape.p95' for a group of the same metric of several estimators."""
    parts = [m.split(".") for m in metrics]
    if all(len(p) == len(parts[0]) and p[0] == parts[0][0] and p[2:] == parts[0][2:] for p in parts):
        return ".".join([parts[0][0], "*", *parts[0][2:]])
    return ", ".join(metrics)


def _group_name(metrics: list[str]) -> str:
    return _common_suffix(metrics).replace("*", "all")


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text)


def _short(value) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


def _hashable(value):
    return json.dumps(value, sort_keys=True) if isinstance(value, (list, dict)) else value
