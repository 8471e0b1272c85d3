"""A baseline: every scored number of every scenario's runs over several seeds, with where they came from.

`riverbench suite --seeds N --save-baseline FILE` writes one; `suite --baseline FILE` and
`riverbench compare-baselines A B` judge another set of runs against it (scenarios.score.regression).
The file is JSON with sorted keys, one metric per line:

    {"format": "riverbench-baseline", "format_version": 1, "created_utc": ..., "provenance": {...},
     "fast": true, "overrides": [],
     "scenarios": {"quickstart": {"seeds": [0, 1, 2], "hashes": [...], "errors": {},
                                  "metrics": {"estimators.ekf.ape.p95": [2.41, 2.38, 2.57], ...}}}}

A metric's list holds one value per seed, in the order of `seeds` (null where nothing was measured
or that seed's run failed; its reason is in `errors`).
"""

from __future__ import annotations

import json
import math
import re
from datetime import UTC, datetime
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from riverbench.atomic import atomic_path
from riverbench.errors import validation_message

FORMAT = "riverbench-baseline"
FORMAT_VERSION = 1
NOT_METRICS = ("expectations", "provenance", "units")
"""Top-level nodes of metrics.json that hold no measured number."""


class ScenarioRuns(BaseModel):
    """One scenario's runs: its seeds, the resolved scenario's hash per seed, every metric per seed."""

    model_config = ConfigDict(extra="forbid")
    seeds: list[int] = Field(description="the seeds run, in order; every list below follows this order")
    hashes: list[str] = Field(description="the resolved scenario's hash without its expectations (Scenario.setup_hash) of each seed's run")
    errors: dict[str, str] = Field(default_factory=dict, description="seed -> why that seed's run failed (its metrics are null)")
    metrics: dict[str, list[float | None]] = Field(description="dotted metrics.json path -> value per seed (null: not measured)")

    @model_validator(mode="after")
    def _aligned(self) -> ScenarioRuns:
        if len(set(self.seeds)) != len(self.seeds):
            raise ValueError("seeds repeat")
        if len(self.hashes) != len(self.seeds):
            raise ValueError(f"{len(self.hashes)} hashes for {len(self.seeds)} seeds")
        for name, values in self.metrics.items():
            if len(values) != len(self.seeds):
                raise ValueError(f"metric {name}: {len(values)} values for {len(self.seeds)} seeds")
        return self

    def values(self, metric: str, seeds: list[int]) -> list[float]:
        """The metric at the given seeds (NaN where not measured or absent)."""
        column = self.metrics.get(metric, [])
        index = {s: i for i, s in enumerate(self.seeds)}
        return [math.nan if (i := index.get(s)) is None or i >= len(column) or column[i] is None else float(column[i]) for s in seeds]


class Baseline(BaseModel):
    """Every scenario's runs over seeds, with the provenance of the code and machine that made them."""

    model_config = ConfigDict(extra="forbid")
    format: str = Field(FORMAT, description="always 'riverbench-baseline'")
    format_version: int = Field(FORMAT_VERSION, description="the file layout's version; another version is refused")
    created_utc: str = Field(description="when the runs finished, ISO 8601 UTC")
    provenance: dict = Field(description="riverbench version, git commit and dirty flag, Python, platform, CPUs, key packages")
    fast: bool = Field(description="whether each scenario's [fast] variant ran")
    overrides: list[str] = Field(default_factory=list, description="--set overrides every run had")
    scenarios: dict[str, ScenarioRuns] = Field(description="scenario name -> its runs")

    def save(self, path: Path) -> None:
        """Write the file atomically (nothing half-written on a crash or Ctrl-C)."""
        text = json.dumps(self.model_dump(mode="json"), indent=1, sort_keys=True, allow_nan=False)
        text = re.sub(r"\[\s+([^\[\]{}]*?)\s+\]", lambda m: "[" + " ".join(m.group(1).split()) + "]", text)  # a metric's seeds on one line
        with atomic_path(Path(path)) as tmp:
            tmp.write_text(text + "\n", encoding="utf-8")


def load(path: Path) -> Baseline:
    """A baseline file, validated; any problem (missing, corrupt, truncated, other format) is one ValueError naming it."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ValueError(f"baseline {path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"baseline {path}: cannot read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"baseline {path}: not valid JSON (truncated or corrupt?): {exc}") from None
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ValueError(f'baseline {path}: not a riverbench baseline (no "format": "{FORMAT}")')
    if data.get("format_version") != FORMAT_VERSION:
        raise ValueError(
            f"baseline {path}: format version {data.get('format_version')!r}; this riverbench reads version "
            f"{FORMAT_VERSION} (make a new baseline with `riverbench suite --save-baseline`)"
        )
    try:
        return Baseline.model_validate(data)
    except ValidationError as exc:
        raise ValueError(validation_message(exc, f"baseline {path}")) from None


def flatten(metrics: dict) -> dict[str, float | None]:
    """Every number of a metrics.json tree by dotted path (booleans as 0/1, null kept; words and lists left out)."""
    out: dict[str, float | None] = {}

    def walk(node, path: str) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                if path or key not in NOT_METRICS:
                    walk(value, f"{path}.{key}" if path else key)
        elif node is None or isinstance(node, (bool, int, float)):
            value = None if node is None else float(node)
            out[path] = value if value is None or math.isfinite(value) else None

    walk(metrics, "")
    return out


def from_runs(runs: dict[str, list[tuple[int, str, dict | None, str]]], *, fast: bool, overrides: list[str], provenance: dict) -> Baseline:
    """A Baseline from finished runs: scenario -> [(seed, scenario hash, metrics.json tree or None, error)]."""
    scenarios = {}
    for name, seeded in runs.items():
        seeded = sorted(seeded, key=lambda r: r[0])
        flat = [flatten(m) if m is not None else {} for _, _, m, _ in seeded]
        keys = sorted({k for f in flat for k in f})
        scenarios[name] = ScenarioRuns(
            seeds=[s for s, *_ in seeded],
            hashes=[h for _, h, _, _ in seeded],
            errors={str(s): e for s, _, _, e in seeded if e},
            metrics={k: [f.get(k) for f in flat] for k in keys},
        )
    return Baseline(
        created_utc=datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"), provenance=provenance, fast=fast, overrides=list(overrides), scenarios=scenarios
    )


def from_cases(cases, *, fast: bool, overrides: list[str], provenance: dict) -> Baseline:
    """A Baseline from a suite's finished cases (scenarios.batch.suite.CaseResult: name, seed, hash, run directory, error)."""
    runs: dict[str, list[tuple[int, str, dict | None, str]]] = {}
    for case in cases:
        metrics = None
        error = case.error
        if not error:
            try:
                metrics = json.loads((Path(case.run_dir) / "metrics.json").read_text(encoding="utf-8"))
            except (OSError, ValueError) as exc:
                error = f"metrics.json unreadable: {exc}"
        runs.setdefault(case.name, []).append((int(case.seed or 0), case.scenario_hash, metrics, error))
    return from_runs(runs, fast=fast, overrides=overrides, provenance=provenance)
