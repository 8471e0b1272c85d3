"""Grouping runs into scenario configurations (repeats over seeds) and each component's numbers over them."""

from __future__ import annotations

import json
from dataclasses import dataclass

import numpy as np

from scenarios.report import run_report as report
from scenarios.report.compare.roc import Roc, monitor_roc
from scenarios.report.compare.runs import RunInfo
from scenarios.report.document import NULL, Column

NOT_CONFIGURATION = ("seed", "description", "fast")
"""Keys of a resolved scenario that leave what runs unchanged (as in its hash), or, the seed, make a repeat."""


def _pick(columns: list[Column], *titles: str) -> list[Column]:
    """The run report's columns of these titles, in this order (one definition of each metric)."""
    by_title = {c.title: c for c in columns}
    return [by_title[t] for t in titles]


ACCURACY = _pick(report.ACCURACY_COLUMNS, "available", "APE rmse (m)", "APE p95 (m)", "APE max (m)", "RPE 100 m (m)", "yaw p95 (°)")
WINDOWS = _pick(report.DEGRADATION_COLUMNS, "blackout max (m)", "NLOS max (m)", "reacquisition max (m)")
MONITOR, *SCORES = _pick(report.DEGRADATION_COLUMNS, "monitor", "faulty fixes", "recall", "false alarms")
MATCHER = _pick(
    report.MATCHER_COLUMNS, "success", "degenerate", "Hz", "time p95 (ms)", "points (median)", "APE aligned rmse (m)", "RPE 100 m (m)", "yaw p95 (°)"
)
AVAILABLE, APE_P95, BLACKOUT, NLOS = ACCURACY[0], ACCURACY[2], WINDOWS[0], WINDOWS[1]
FAULTY, RECALL, FALSE_ALARMS = SCORES
SUCCESS, HZ, APE_ALIGNED = MATCHER[0], MATCHER[2], MATCHER[5]


@dataclass(frozen=True)
class Spread:
    """A metric over the runs of one configuration: median, min, max, and how many runs gave a value."""

    median: float
    lo: float
    hi: float
    n: int


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
            out.append(
                _configuration(scenario, label_text(flat[i], differing), sorted(members[i], key=lambda r: (r.seed is None, r.seed or 0, str(r.path))))
            )
    return out


def label_text(flat: dict[str, object], keys: list[str]) -> str:
    """'key=value, ...' of a flattened configuration."""
    return ", ".join(f"{k}={value_text(flat.get(k))}" for k in keys)


def label_keys(flat: list[dict[str, object]]) -> list[str]:
    """The dotted keys whose values differ between a scenario's configurations; those that every configuration sets when
    they suffice to tell them apart (a key only some set is mostly a default that follows from another, e.g. a monitor's params);
    else without the parameters of a component whose kind differs (they follow from it) when the rest still tells them apart."""
    keys = list(dict.fromkeys(k for f in flat for k in f))
    differing = [k for k in keys if len({value_text(f.get(k)) for f in flat}) > 1]
    shared = [k for k in differing if all(k in f for f in flat)]
    if len({label_text(f, shared) for f in flat}) == len(flat):
        return shared
    owners = [k.removesuffix(".kind") for k in differing if k.endswith(".kind")]  # a component added, removed or of another kind
    brief = [k for k in differing if not any(k.startswith(f"{o}.") and k != f"{o}.kind" for o in owners)]
    return brief if len({label_text(f, brief) for f in flat}) == len(flat) else differing


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
        out[cid] = {
            **{c.title: spread_of([c.value(node) for node in good]) for c in columns},
            "failures": len(present) - len(good),
            "runs": len(present),
            "monitor_kind": monitors.get(cid, "none"),
        }
    return out


def spread_of(values: list) -> Spread | None:
    """Median, min and max of the finite values (None when there are none)."""
    v = np.array([np.nan if x is None else x for x in values], dtype=float)
    v = v[np.isfinite(v)]
    return Spread(float(np.median(v)), float(v.min()), float(v.max()), len(v)) if len(v) else None
