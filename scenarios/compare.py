"""The algorithm comparison report: estimators and scan matchers across scenarios, configurations and seeds.

`write(sources, out_dir)` finds every run directory under the sources (a run, a suite or a sweep
directory, at any depth; hidden directories are runs in progress and are skipped), groups the runs
by scenario and configuration (the resolved scenario without its seed: runs that differ only in
seed are repeats), and writes report.md, a self-contained report.html and plots/roc-*.png. Every
number is the median over a configuration's seeds with its range (min–max), so a reader can tell a
real difference from noise; the written summary says which differences exceed that range. The
report is built from the run report's blocks and renderers (scenarios.report).
"""

from __future__ import annotations

import json
import os
import re
import textwrap
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import tomllib
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import PercentFormatter

from scenarios import plots, report
from scenarios.atomic import atomic_dir
from scenarios.metrics import FAULT_M, roc
from scenarios.report import NULL, Cell, Column, Heading, Image, Table, Text

NOT_CONFIGURATION = ("seed", "description", "fast")
"""Keys of a resolved scenario that leave what runs unchanged (as in its hash), or, the seed, make a repeat."""
OPEN_WATER = "open_river"
"""The scenario whose results the summary calls open water."""
ZOOM_FA = 0.1
"""The right-hand ROC panel shows false-alarm rates up to this."""
SPREAD_NOTE = ("Median over seeds (min–max over seeds) of the runs in which the component did not fail (failed runs are counted "
               "apart); bold: best median in its column.")
VERDICTS = {"clear": "a clear difference", "within": "within the spread: no clear winner",
            "unknown": "the spread is unknown (one seed)"}
TALLY_WORDS = {"clear": "clear", "within": "within the spread", "unknown": "with one seed"}
"""How the tally of wins words each verdict: 'clear in 2, within the spread in 1'."""


def _pick(columns: list[Column], *titles: str) -> list[Column]:
    """The run report's columns of these titles, in this order (one definition of each metric)."""
    by_title = {c.title: c for c in columns}
    return [by_title[t] for t in titles]


ACCURACY = _pick(report.ACCURACY_COLUMNS, "APE rmse", "APE p95", "APE max", "RPE 100 m", "yaw p95 (°)")
WINDOWS = _pick(report.DEGRADATION_COLUMNS, "blackout max", "NLOS max", "reacquisition max")
MONITOR, *SCORES = _pick(report.DEGRADATION_COLUMNS, "monitor", "recall", "false alarms")
MATCHER = _pick(report.MATCHER_COLUMNS, "success", "degenerate", "Hz", "ms p95", "points median", "APE aligned rmse", "RPE 100 m", "yaw p95 (°)")
APE_P95, BLACKOUT, NLOS = ACCURACY[1], WINDOWS[0], WINDOWS[1]
SUCCESS, HZ, APE_ALIGNED = MATCHER[0], MATCHER[2], MATCHER[5]


@dataclass(frozen=True)
class RunInfo:
    """One run directory: where it is, its scenario name, seed and hash, its resolved scenario and its metrics."""

    path: Path
    scenario: str
    seed: int | None
    hash: str
    config: dict
    metrics: dict


@dataclass(frozen=True)
class Unfinished:
    """A suite case that left no run directory (crashed, timed out): its scenario and why."""

    scenario: str
    reason: str
    suite_file: Path


@dataclass(frozen=True)
class Spread:
    """A metric over the runs of one configuration: median, min, max, and how many runs gave a value."""

    median: float
    lo: float
    hi: float
    n: int


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


@dataclass(frozen=True)
class Configuration:
    """The runs of one scenario configuration (repeats over seeds) and each estimator's and matcher's numbers over them.

    `estimators` and `matchers` map an id to {column title: Spread or None, "failures", "runs", "monitor_kind"}.
    """

    scenario: str
    label: str
    runs: list[RunInfo]
    estimators: dict[str, dict]
    matchers: dict[str, dict]
    roc: Roc

    @property
    def title(self) -> str:
        """The scenario name, and the keys that set this configuration apart from the scenario's others."""
        return f"{self.scenario} ({self.label})" if self.label else self.scenario


@dataclass(frozen=True)
class Criterion:
    """What the written summary compares: a phrase, the column whose medians it ranks, the unit after the numbers."""

    phrase: str
    column: Column
    unit: str
    kind: str  # "estimators" or "matchers"


@dataclass(frozen=True)
class Duel:
    """The best component of one criterion in one configuration, and the runner-up."""

    winner: str
    best: Spread
    runner_up: str
    second: Spread


CRITERIA = (
    Criterion("Lowest APE p95", APE_P95, " m", "estimators"),
    Criterion("Under bridges (worst error in blackout windows)", BLACKOUT, " m", "estimators"),
    Criterion("Beside walls and in canals (worst error in NLOS windows)", NLOS, " m", "estimators"),
    Criterion("Highest matching success", SUCCESS, "", "matchers"),
    Criterion("Lowest aligned APE rmse of the matcher odometry", APE_ALIGNED, " m", "matchers"),
    Criterion("Fastest matcher", HZ, " Hz", "matchers"),
)


# ---- public API -------------------------------------------------------------------------------------

def write(sources: list[Path], out_dir: Path) -> Path:
    """Write report.md, report.html (self-contained, images embedded as data: URIs) and plots/*.png into out_dir; return report.html."""
    out_dir = Path(out_dir)
    run_dirs, listings = find(sources)
    if (out_dir / "metrics.json").exists():
        raise ValueError(f"{out_dir}: is a run directory (its own report would be replaced); write the comparison elsewhere")
    confs = configurations([read_run(p) for p in run_dirs])
    stopped = unfinished(listings)
    with atomic_dir(out_dir) as tmp:
        images = draw_rocs(confs, tmp)
        blocks = build(confs, images, stopped, out_dir)
        (tmp / "report.md").write_text(report.to_markdown(blocks), encoding="utf-8")
        (tmp / "report.html").write_text(report.to_html(blocks, tmp, title="riverbench comparison"), encoding="utf-8")
    return out_dir / "report.html"


def collect(sources: list[Path]) -> list[RunInfo]:
    """Every run directory under the sources, read (bad input raises ValueError naming the path)."""
    return [read_run(p) for p in find(sources)[0]]


def summary_markdown(sources: list[Path]) -> str:
    """The cross-scenario summary tables (estimators' APE p95; matchers' success, aligned APE, Hz) as Markdown, e.g. for the README."""
    return report.to_markdown(summary_blocks(configurations(collect(sources))))


def summary_sentences(sources: list[Path]) -> list[str]:
    """The written summary over every configuration: who wins where, and whether by more than the spread."""
    return overall_sentences(configurations(collect(sources)))


# ---- finding and reading runs -----------------------------------------------------------------------

def find(sources: list[Path]) -> tuple[list[Path], list[Path]]:
    """The run directories, and the suite.json and sweep results.parquet files, under the sources, in path order, hidden directories skipped."""
    if not sources:
        raise ValueError("no run, suite or sweep directory given")
    run_dirs: list[Path] = []
    listings: list[Path] = []
    for source in map(Path, sources):
        if not source.exists():
            raise ValueError(f"{source}: no such file or directory")
        if not source.is_dir():
            raise ValueError(f"{source}: not a directory (give a run, suite or sweep directory)")
        found = []
        for root, dirs, files in os.walk(source):
            dirs[:] = sorted(d for d in dirs if not d.startswith("."))
            if "metrics.json" in files and "scenario.toml" in files:
                found.append(Path(root))
                dirs[:] = []  # a run directory holds no runs
            elif "suite.json" in files:
                listings.append(Path(root) / "suite.json")
            elif "results.parquet" in files and "sweep.json" in files:
                listings.append(Path(root) / "results.parquet")
        if not found:
            raise ValueError(f"{source}: no run directory (one with metrics.json and scenario.toml) in it or below it")
        run_dirs += found
    return _unique(run_dirs), _unique(listings)


def _unique(paths: list[Path]) -> list[Path]:
    """The paths without repeats (overlapping sources), first occurrence kept."""
    seen: dict[Path, Path] = {}
    for path in paths:
        seen.setdefault(path.resolve(), path)
    return list(seen.values())


def read_run(path: Path) -> RunInfo:
    """A run directory's metrics.json and scenario.toml, with its scenario name, seed and hash."""
    metrics = _read(path / "metrics.json", json.loads, "JSON", dict)
    config = _read(path / "scenario.toml", tomllib.loads, "TOML", dict)
    for kind in ("estimators", "matchers"):
        nodes = metrics.get(kind, {})
        if not isinstance(nodes, dict) or not all(isinstance(node, dict) for node in nodes.values()):
            raise ValueError(f"{path / 'metrics.json'}: '{kind}' is not a table of components")
    run = metrics.get("run") if isinstance(metrics.get("run"), dict) else {}
    seed = run.get("seed", config.get("seed"))
    return RunInfo(path, str(run.get("scenario") or config.get("name") or path.name), seed if isinstance(seed, int) else None,
                   str(run.get("scenario_hash") or ""), config, metrics)


def _read(file: Path, parse: Callable[[str], object], what: str, kind: type):
    """A parsed file, or ValueError in one line naming it."""
    try:
        tree = parse(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:  # JSONDecodeError and TOMLDecodeError are ValueErrors
        raise ValueError(f"{file}: unreadable {what} ({' '.join(str(exc).split())})") from None
    if not isinstance(tree, kind):
        raise ValueError(f"{file}: not the expected {what} {'object' if kind is dict else 'list'}")  # noqa: TRY004 (bad input is a ValueError)
    return tree


def unfinished(listings: list[Path]) -> list[Unfinished]:
    """The suite cases and sweep runs that failed (they left no run directory to compare)."""
    out = []
    for f in listings:
        if f.name == "results.parquet":
            from scenarios import sweep_table

            out += [Unfinished(f"{r['scenario']} (seed {r['seed']})", str(r.get("reason") or r["status"]), f)
                    for r in sweep_table.read(f.parent) if r.get("status") != "ok"]
        else:
            out += [Unfinished(str(case.get("name", NULL)), str(case["error"]), f)
                    for case in _read(f, json.loads, "JSON", list) if isinstance(case, dict) and case.get("error")]
    return out


# ---- grouping ---------------------------------------------------------------------------------------

def configuration(config: dict) -> dict:
    """The resolved scenario without the keys that do not change what runs (seed: repeats)."""
    return {k: v for k, v in config.items() if k not in NOT_CONFIGURATION}


def flatten(tree: dict, prefix: str = "") -> dict[str, object]:
    """A TOML tree as dotted keys; lists of tables by their id (else index): matchers.gicp.params.voxel_m."""
    out: dict[str, object] = {}
    for key, value in tree.items():
        path = f"{prefix}{key}"
        if isinstance(value, dict):
            out.update(flatten(value, f"{path}."))
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            for i, item in enumerate(value):
                out.update(flatten({k: v for k, v in item.items() if k != "id"}, f"{path}.{item.get('id', i)}."))
        else:
            out[path] = value
    return out


def value_text(value) -> str:
    """A configuration value as a label shows it: strings bare, TOML booleans, numbers and lists as JSON, absent as '–'."""
    if value is None:
        return NULL
    if isinstance(value, str):
        return value
    if isinstance(value, bool):
        return "true" if value else "false"
    return json.dumps(value, default=str)


def _order(value) -> tuple:
    """Sort key of a configuration value: numbers by value, then text, then absent."""
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return (0, value, "")
    return (1, 0, value_text(value)) if value is not None else (2, 0, "")


def configurations(runs: list[RunInfo]) -> list[Configuration]:
    """The runs grouped by scenario and configuration: scenarios by name, a scenario's configurations by the values that differ."""
    groups: dict[tuple[str, str], list[RunInfo]] = {}
    for run in runs:
        groups.setdefault((run.scenario, json.dumps(configuration(run.config), sort_keys=True, default=str)), []).append(run)
    out = []
    for scenario in sorted({s for s, _ in groups}):
        members = [rs for (s, _), rs in groups.items() if s == scenario]
        flat = [flatten(configuration(rs[0].config)) for rs in members]
        differing = label_keys(flat)
        for i in sorted(range(len(members)), key=lambda i: tuple(_order(flat[i].get(k)) for k in differing)):
            out.append(_configuration(scenario, label_text(flat[i], differing),
                                      sorted(members[i], key=lambda r: (r.seed is None, r.seed or 0, str(r.path)))))
    return out


def label_text(flat: dict[str, object], keys: list[str]) -> str:
    """'key=value, ...' of a flattened configuration."""
    return ", ".join(f"{k}={value_text(flat.get(k))}" for k in keys)


def label_keys(flat: list[dict[str, object]]) -> list[str]:
    """The dotted keys whose values differ between a scenario's configurations; those that every configuration sets when
    they suffice to tell them apart (a key only some set is mostly a default that follows from another, e.g. a monitor's params)."""
    keys = list(dict.fromkeys(k for f in flat for k in f))
    differing = [k for k in keys if len({value_text(f.get(k)) for f in flat}) > 1]
    shared = [k for k in differing if all(k in f for f in flat)]
    return shared if len({label_text(f, shared) for f in flat}) == len(flat) else differing


def _configuration(scenario: str, label: str, runs: list[RunInfo]) -> Configuration:
    """A configuration with its components' numbers over its runs and its monitors' ROC."""
    monitors = {e["id"]: str(e.get("monitor", "none")) for e in runs[0].config.get("estimators", []) if isinstance(e, dict) and "id" in e}
    estimators = components(runs, "estimators", [*ACCURACY, *WINDOWS, *SCORES], monitors)
    matchers = components(runs, "matchers", MATCHER, {})
    return Configuration(scenario, label, runs, estimators, matchers, monitor_roc(runs, list(estimators), monitors))


def failed(run: RunInfo, kind: str, cid: str) -> bool:
    """Whether an estimator or matcher (kind 'estimators'/'matchers') failed in the run: its own flag or the run's failure list."""
    component = kind.removesuffix("s")
    failures = (run.metrics.get("run") or {}).get("failures") or []
    return bool(run.metrics[kind][cid].get("failed")) or any(f.get("component") == component and f.get("id") == cid for f in failures)


def components(runs: list[RunInfo], kind: str, columns: list[Column], monitors: dict[str, str]) -> dict[str, dict]:
    """Per component id: each column's Spread over the runs in which it did not fail, its failures, runs and monitor."""
    ids = list(dict.fromkeys(cid for r in runs for cid in r.metrics.get(kind) or {}))
    out = {}
    for cid in ids:
        present = [r for r in runs if cid in (r.metrics.get(kind) or {})]
        good = [r.metrics[kind][cid] for r in present if not failed(r, kind, cid)]
        if monitors.get(cid, "none") == "none":  # no monitor: its scores mean nothing
            good = [{k: v for k, v in node.items() if k != "monitor"} for node in good]
        out[cid] = {**{c.title: spread_of([c.value(node) for node in good]) for c in columns},
                    "failures": len(present) - len(good), "runs": len(present), "monitor_kind": monitors.get(cid, "none")}
    return out


def spread_of(values: list) -> Spread | None:
    """Median, min and max of the finite values (None when there are none)."""
    v = np.array([np.nan if x is None else x for x in values], dtype=float)
    v = v[np.isfinite(v)]
    return Spread(float(np.median(v)), float(v.min()), float(v.max()), len(v)) if len(v) else None


# ---- monitor ROC ------------------------------------------------------------------------------------

def read_gps(run: RunInfo, eids: list[str]) -> dict[str, np.ndarray]:
    """gps.csv's quality, added error and each estimator's verdict and statistic as floats (empty without the file)."""
    path = run.path / "gps.csv"
    table = plots.read_csv(path)
    if "quality" not in table or "added_err_h" not in table:
        return {}
    n = len(table["quality"])
    wanted = {"quality": table["quality"], "added_err_h": table["added_err_h"],
              **{f"{e}.{k}": table.get(f"{e}.{k}", np.full(n, fill)) for e in eids for k, fill in (("trusted", 1.0), ("statistic", np.nan))}}
    bad = [name for name, column in wanted.items() if column.dtype.kind != "f"]
    if bad:
        raise ValueError(f"{path}: column {bad[0]} holds something other than numbers")
    return wanted


def monitor_roc(runs: list[RunInfo], eids: list[str], monitors: dict[str, str]) -> Roc:
    """The ROC of each estimator with a monitor over the measured fixes of all runs, pooled (faulty: > 5 m added by the environment)."""
    tables = [t for t in (read_gps(r, eids) for r in runs) if t]
    measured = [t["quality"] == 1 for t in tables]
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


def roc_path(index: int, conf: Configuration) -> str:
    """The ROC figure's path relative to the report: numbered (unique) and named after the configuration."""
    return f"plots/roc-{index:02d}-{re.sub(r'[^A-Za-z0-9_.=-]+', '_', conf.title).strip('_')[:60]}.png"


def draw_rocs(confs: list[Configuration], out_dir: Path) -> dict[str, str]:
    """Draw the ROC figure of each configuration with faulty fixes and a monitor; returns {configuration title: relative path}."""
    written = {}
    for index, conf in enumerate(confs):
        if conf.roc.curves:
            path = roc_path(index, conf)
            (out_dir / path).parent.mkdir(parents=True, exist_ok=True)
            roc_figure(conf).savefig(out_dir / path, format="png", dpi=plots.DPI)
            written[conf.title] = path
    return written


def roc_figure(conf: Configuration) -> Figure:
    """Recall against false-alarm rate of each monitor, its verdicts as a dot: whole range (left), the first 10 % of false alarms (right)."""
    figure = Figure(figsize=(plots.WIDTH_IN, 5.2), layout="constrained")
    axes = figure.subplots(1, 2)
    palette = {eid: plots.TRACK_COLOURS[i % len(plots.TRACK_COLOURS)] for i, eid in enumerate(conf.estimators)}
    handles = []
    for curve in conf.roc.curves:
        fa, recall = curve.operating
        label = f"{curve.eid} (monitor {curve.monitor}): its verdicts flag {report.share(recall)} of faulty fixes at {report.share(fa)} false alarms"
        for ax in axes:
            line, = ax.plot(curve.false_alarm, curve.recall, color=palette[curve.eid], lw=1.5, label=label)
            ax.plot(fa, recall, marker="o", ms=8, color=palette[curve.eid], mec="black", mew=0.8, ls="none", zorder=5)
        handles.append(line)
    axes[0].plot([0, 1], [0, 1], color="grey", lw=0.8, ls=":")
    handles += [Line2D([], [], marker="o", ls="none", mfc="white", mec="black", ms=8, label="dot: the operating point of its actual verdicts"),
                Line2D([], [], color="grey", lw=0.8, ls=":", label="chance")]
    for ax, right, title in zip(axes, (1.0, ZOOM_FA), ("whole range", f"false-alarm rates up to {ZOOM_FA:.0%}")):
        ax.set_xlim(0, right)
        ax.set_ylim(0, 1.02)
        ax.xaxis.set_major_formatter(PercentFormatter(1.0, decimals=0))
        ax.yaxis.set_major_formatter(PercentFormatter(1.0, decimals=0))
        ax.set_xlabel("false-alarm rate (clean measured fixes flagged)")
        ax.set_title(title, fontsize=10)
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("recall (faulty fixes flagged)")
    figure.suptitle(textwrap.fill(f"{conf.title}: {conf.roc.faulty} faulty of {conf.roc.measured} measured fixes over "
                                  f"{_plural(len(conf.runs), 'run')}", 130), fontsize=11)
    figure.legend(handles=handles, loc="outside lower center", ncol=1, fontsize=8)
    return figure


# ---- the written summary ----------------------------------------------------------------------------

def duel(nodes: dict[str, dict], column: Column) -> Duel | None:
    """The best and second-best component by median in this column (None with fewer than two values)."""
    scored = [(cid, node[column.title]) for cid, node in nodes.items() if node.get(column.title)]
    if len(scored) < 2:
        return None
    scored.sort(key=lambda item: item[1].median, reverse=column.better == "high")
    (winner, best), (runner_up, second) = scored[:2]
    return Duel(winner, best, runner_up, second)


def verdict(d: Duel, column: Column) -> str:
    """'tie' (equal as printed), 'unknown' (a single seed), 'clear' (the ranges over seeds do not overlap) or 'within'."""
    if column.fmt(d.best.median) == column.fmt(d.second.median):
        return "tie"
    if min(d.best.n, d.second.n) < 2:
        return "unknown"
    apart = d.best.hi < d.second.lo if column.better == "low" else d.best.lo > d.second.hi
    return "clear" if apart else "within"


def quote(s: Spread, criterion: Criterion, seeds: bool) -> str:
    """'2.80 m (2.60–3.10 over 3 seeds)': the median and its range over seeds."""
    fmt = criterion.column.fmt
    text = f"{fmt(s.median)}{criterion.unit}"
    if s.n < 2:
        return f"{text} (1 seed)"
    return f"{text} ({fmt(s.lo)}–{fmt(s.hi)}{f' over {s.n} seeds' if seeds else ''})"


def sentence(criterion: Criterion, d: Duel) -> str:
    """One factual sentence: the winner against the runner-up, and whether the gap exceeds the spread over seeds."""
    v = verdict(d, criterion.column)
    if v == "tie":
        return f"{criterion.phrase}: {d.winner} and {d.runner_up} tie at {criterion.column.fmt(d.best.median)}{criterion.unit}."
    return (f"{criterion.phrase}: {d.winner} {quote(d.best, criterion, True)} against {d.runner_up} "
            f"{quote(d.second, criterion, d.second.n != d.best.n)}: {VERDICTS[v]}.")


def conf_sentences(conf: Configuration) -> list[str]:
    """Per criterion with two or more components to compare, who wins in this configuration."""
    return [sentence(c, d) for c in CRITERIA if (d := duel(getattr(conf, c.kind), c.column))]


def tally(confs: list[Configuration], criterion: Criterion) -> str | None:
    """Which component wins the criterion in how many configurations, and how many of those wins are clear."""
    duels = [d for c in confs if (d := duel(getattr(c, criterion.kind), criterion.column))]
    if not duels:
        return None
    wins: dict[str, list[str]] = {}
    for d in duels:
        wins.setdefault(d.winner if verdict(d, criterion.column) != "tie" else "", []).append(verdict(d, criterion.column))
    ties = len(wins.pop("", []))
    parts = [f"{winner} in {len(codes)} of {_plural(len(duels), 'configuration')} ("
             + ", ".join(f"{word} in {codes.count(code)}" for code, word in TALLY_WORDS.items() if code in codes) + ")"
             for winner, codes in sorted(wins.items(), key=lambda item: -len(item[1]))]
    return f"{criterion.phrase}: " + "; ".join(parts + ([f"a tie in {ties}"] if ties else [])) + "."


def overall_sentences(confs: list[Configuration]) -> list[str]:
    """The summary over all configurations: wins per criterion, open water, failures."""
    out = [t for c in CRITERIA if (t := tally(confs, c))]
    for conf in (c for c in confs if c.scenario == OPEN_WATER):
        if d := duel(conf.estimators, APE_P95):
            out.append(sentence(replace(CRITERIA[0], phrase=f"Open water ({conf.title}), lowest APE p95"), d))
    failures = [f"{cid} ({kind.removesuffix('s')}) in {node['failures']} of {_plural(node['runs'], 'run')} of {conf.title}"
                for conf in confs for kind in ("estimators", "matchers") for cid, node in getattr(conf, kind).items() if node["failures"]]
    out.append("Failed: " + "; ".join(failures) + "." if failures else "No estimator or matcher failed in any run.")
    return out


# ---- blocks -----------------------------------------------------------------------------------------

def _plural(n: int, word: str) -> str:
    """'1 run', '3 runs'."""
    return f"{n} {word}{'' if n == 1 else 's'}"


def seeds_text(seeds: list[int | None]) -> str:
    """The seeds as a range when consecutive ('0–4'), else listed."""
    known = sorted({s for s in seeds if s is not None})
    if len(known) > 2 and known == list(range(known[0], known[-1] + 1)):
        return f"{known[0]}–{known[-1]}"
    return ", ".join(map(str, known)) or NULL


def build(confs: list[Configuration], images: dict[str, str], stopped: list[Unfinished], out_dir: Path) -> list:
    """Every block of the comparison report, in reading order."""
    return [*header(confs), *summary_section(confs), *(b for conf in confs for b in conf_section(conf, images)),
            *unfinished_section(stopped, out_dir), *runs_section(confs, out_dir)]


def header(confs: list[Configuration]) -> list:
    """Title and what was compared: runs, scenarios, configurations, seeds."""
    runs = [r for c in confs for r in c.runs]
    names = sorted({c.scenario for c in confs})
    per = sorted({len(c.runs) for c in confs})
    meta = (f"{_plural(len(runs), 'run')} · {_plural(len(names), 'scenario')} ({', '.join(names)}) · {_plural(len(confs), 'configuration')} · "
            f"seeds {seeds_text([r.seed for r in runs])} ({'–'.join(map(str, (per[0], per[-1]) if len(per) > 1 else per))} per configuration)")
    return [Heading(1, "riverbench comparison"), Text(meta, "meta"),
            Text("Each number is the median over the seeds of a configuration, in brackets the range (min–max) over those seeds. "
                 "A difference is called clear when the two ranges do not overlap; with one seed the spread is unknown.", "note")]


def summary_section(confs: list[Configuration]) -> list:
    """The written summary over all configurations, then the cross-scenario tables."""
    return [Heading(2, "Summary"), *(Text(s) for s in overall_sentences(confs)), *summary_blocks(confs)]


def summary_blocks(confs: list[Configuration]) -> list:
    """Estimators' APE p95 and matchers' success, aligned APE rmse and Hz: a row per component, a column per configuration."""
    blocks = [Heading(3, "Estimators: APE p95 (m)"), cross_table("estimator", confs, "estimators", APE_P95)]
    if any(c.matchers for c in confs):
        for title, column in (("Matchers: success", SUCCESS), ("Matchers: aligned APE rmse (m)", APE_ALIGNED), ("Matchers: speed (Hz)", HZ)):
            blocks += [Heading(3, title), cross_table("matcher", confs, "matchers", column)]
    return blocks


def spread_text(s: Spread | None, fmt: Callable) -> str:
    """' (lo–hi)' after a median, or nothing with fewer than two values."""
    return f" ({fmt(s.lo)}–{fmt(s.hi)})" if s is not None and s.n > 1 else ""


def spread_column(title: str, base: Column, locate: Callable[[dict], dict], failures: bool = False) -> Column:
    """A column over aggregated nodes: `locate` finds the component's node, whose Spread under base's title is ranked by its median and printed with its range."""
    def median(node: dict) -> float | None:
        """The median, ranked and printed first."""
        s = locate(node).get(base.title)
        return None if s is None else s.median

    def detail(node: dict) -> str:
        """The range over seeds, and with `failures` how many runs failed."""
        mine = locate(node)
        text = spread_text(mine.get(base.title), base.fmt)
        return text + (f" [{mine['failures']} of {mine['runs']} runs failed]" if failures and mine.get("failures") else "")

    return Column(title, median, base.fmt, base.better, detail=detail)


def _itself(node: dict) -> dict:
    """A per-configuration table's node is the component's own."""
    return node


FAILURE_COLUMN = Column("failure rate", lambda n: n["failures"] / n["runs"] if n["runs"] else None, report.share, None,
                        detail=lambda n: f" ({n['failures']}/{n['runs']})")
"""Share of a configuration's runs in which the component failed (not ranked: no failure is no merit)."""


def cross_table(first: str, confs: list[Configuration], kind: str, base: Column) -> Table:
    """A row per configuration, a column per component id: the base metric's median over seeds with its range; the
    row's best in bold (who wins where reads along a row)."""
    ids = list(dict.fromkeys(cid for c in confs for cid in getattr(c, kind)))
    rows = []
    for conf in confs:
        nodes = getattr(conf, kind)
        spreads = {cid: nodes.get(cid, {}).get(base.title) for cid in ids}
        medians = {cid: s.median for cid, s in spreads.items() if s is not None and s.median == s.median}
        texts = {cid: base.fmt(medians.get(cid)) for cid in ids}
        best = None
        if base.better and len(set(texts[c] for c in medians)) > 1:
            best = texts[(min if base.better == "low" else max)(medians, key=medians.get)]
        cells = [report.Cell(conf.title, css="text")]
        for cid in ids:
            node = nodes.get(cid, {})
            failed = f" [{node['failures']} of {node['runs']} runs failed]" if node.get("failures") else ""
            cells.append(report.Cell(texts[cid] + spread_text(spreads[cid], base.fmt) + failed, bold=texts[cid] == best))
        rows.append(cells)
    return Table(["scenario", *ids], rows, SPREAD_NOTE.replace("best median in its column", "best median in its row"))


def conf_section(conf: Configuration, images: dict[str, str]) -> list:
    """One configuration: what it is, who wins, the ranked tables and the monitors' ROC."""
    info = conf.runs[0].config
    blocks: list = [Heading(2, conf.title)]
    if info.get("description"):
        blocks.append(Text(str(info["description"])))
    blocks.append(Text(f"world {info.get('world', NULL)} · stretch {report.stretch_text(info.get('stretch') or {})} · "
                       f"{_plural(len(conf.runs), 'run')}, seeds {seeds_text([r.seed for r in conf.runs])}", "meta"))
    blocks += [Text(s) for s in conf_sentences(conf)]
    blocks += estimator_tables(conf) + matcher_tables(conf) + roc_blocks(conf, images)
    return blocks


def estimator_tables(conf: Configuration) -> list:
    """Accuracy with the failure rate, then worst errors through GPS degradation and the monitor's scores."""
    nodes = conf.estimators
    if not nodes:
        return []
    labels = {cid: cid for cid in nodes}
    accuracy = report.ranked_table("estimator", nodes, [*(spread_column(c.title, c, _itself) for c in ACCURACY), FAILURE_COLUMN], labels,
                                   "Horizontal errors in metres; RPE: mean error per 100 m of true travel; failure rate: share of runs in "
                                   "which the estimator failed. " + SPREAD_NOTE)
    present = [c for c in [*WINDOWS, *SCORES] if any(n.get(c.title) for n in nodes.values())]
    blocks = [Heading(3, "Estimators"), accuracy]
    if present:
        columns = [spread_column(c.title, c, _itself) for c in present if c in WINDOWS] + [MONITOR]
        columns += [spread_column(c.title, c, _itself) for c in present if c in SCORES]
        blocks.append(report.ranked_table("estimator", nodes, columns, labels,
                                          "Worst horizontal error (m) inside any window of that kind (blackout: under bridges; NLOS: "
                                          "reflected signals beside walls). Monitor: recall and false-alarm rate on measured fixes whose "
                                          "environment-added error exceeds 5 m. " + SPREAD_NOTE))
    return blocks


def matcher_tables(conf: Configuration) -> list:
    """Success, degeneracy, speed, points and odometry accuracy of each matcher, with its failure rate."""
    if not conf.matchers:
        return []
    columns = [*(spread_column(c.title, c, _itself) for c in MATCHER), FAILURE_COLUMN]
    note = ("Success: share of scans with a usable match; degenerate: usable matches with an unobserved direction; errors (m) of the "
            "odometry chained from the true start, APE aligned after the best-fit planar motion. " + SPREAD_NOTE)
    return [Heading(3, "Scan matchers"), report.ranked_table("matcher", conf.matchers, columns, {cid: cid for cid in conf.matchers}, note)]


def roc_blocks(conf: Configuration, images: dict[str, str]) -> list:
    """The ROC figure, or why there is none."""
    if conf.title in images:
        caption = (f"Monitor ROC over the {conf.roc.measured} measured fixes of {_plural(len(conf.runs), 'run')}, pooled: recall (share of the "
                   f"{conf.roc.faulty} fixes with more than {FAULT_M:g} m added by the environment that are flagged) against false-alarm rate "
                   f"(share of the others flagged), linear axes, each threshold of the monitor's statistic; dot: its actual verdicts, which can "
                   f"lie off the curve (a combined monitor, a hold after an alarm, fixes refused before initialisation). "
                   f"Right: false-alarm rates up to {ZOOM_FA:.0%}.")
        return [Heading(3, "Monitor ROC"), Image(images[conf.title], caption)]
    why = (f"No measured fix had more than {FAULT_M:g} m added by the environment" if not conf.roc.faulty
           else "No estimator here has a monitor with a statistic")
    return [Heading(3, "Monitor ROC"), Text(f"{why}: no ROC curve.")]


def unfinished_section(stopped: list[Unfinished], out_dir: Path) -> list:
    """Suite cases and sweep runs that left no run directory (none: no section)."""
    if not stopped:
        return []
    rows = [[Cell(u.scenario, css="fail"), Cell(u.reason, css="text"), Cell(_relative(u.suite_file, out_dir), css="text")] for u in stopped]
    return [Heading(2, "Runs that did not finish"), Table(["scenario", "reason", "listed in"], rows, "These runs are in no table above.")]


def _relative(path: Path, out_dir: Path) -> str:
    """A path relative to the report's directory."""
    return os.path.relpath(Path(path).absolute(), Path(out_dir).absolute())


def runs_section(confs: list[Configuration], out_dir: Path) -> list:
    """Every run compared: configuration, seed, hash, path, expectations passed, failed components."""
    rows = []
    for conf in confs:
        for run in conf.runs:
            outcomes = run.metrics.get("expectations") or []
            passed = sum(bool(o.get("pass")) for o in outcomes)
            broken = [cid for kind in ("estimators", "matchers") for cid in run.metrics.get(kind) or {} if failed(run, kind, cid)]
            rows.append([Cell(conf.title, css="text"), Cell(NULL if run.seed is None else str(run.seed)), Cell(run.hash or NULL),
                         Cell(_relative(run.path, out_dir), css="text"),
                         Cell(f"{passed}/{len(outcomes)}", css=("pass" if passed == len(outcomes) else "fail") if outcomes else ""),
                         Cell(", ".join(broken), css="fail" if broken else "")])
    return [Heading(2, "Runs"), Table(["configuration", "seed", "hash", "path", "expectations passed", "failed"], rows,
                                      "Paths relative to this report.")]
