"""A sweep's results table: one row per run, Parquet (typed, for pandas/polars/pyarrow) and CSV beside it.

Columns: the run's identity (scenario, scenario_hash, seed, status, reason, wall_s, run_dir,
passed), each swept parameter as `param.<key>`, and every numeric metric of metrics.json
flattened to its dotted path (`estimators.ekf.ape.p95`); lists become counts (`run.failures`,
`expectations.passed`, `expectations.failed`). Both files are rewritten under a temporary name
after every run, so a killed sweep leaves a consistent table of the runs that finished.
"""

from __future__ import annotations

import csv
import json
from collections.abc import Iterable
from pathlib import Path

from riverbench.atomic import atomic_path

PARQUET = "results.parquet"
CSV = "results.csv"
IDENTITY = ("scenario", "scenario_hash", "seed", "status", "reason", "wall_s", "run_dir", "passed")
PARAM_PREFIX = "param."


def flatten(metrics: dict) -> dict:
    """Numeric leaves of a metrics tree by dotted path; run.failures and expectations as counts; text left out."""
    out: dict = {}

    def walk(node, path: str) -> None:
        if isinstance(node, dict):
            for key, value in node.items():
                walk(value, f"{path}.{key}" if path else str(key))
        elif isinstance(node, bool) or (isinstance(node, (int, float)) and not isinstance(node, bool)):
            out[path] = node
        elif node is None:
            out[path] = None

    walk({k: v for k, v in metrics.items() if k not in ("expectations", "provenance")}, "")
    out["run.failures"] = len(metrics.get("run", {}).get("failures", []))
    outcomes = metrics.get("expectations", [])
    out["expectations.passed"] = sum(bool(o.get("pass")) for o in outcomes)
    out["expectations.failed"] = sum(not o.get("pass") for o in outcomes)
    return out


def row(point, status: str, wall_s: float, run_dir: str, metrics: dict | None = None, reason: str = "") -> dict:
    """The table row of one finished (or failed) run of a sweep point."""
    outcomes = (metrics or {}).get("expectations", [])
    return {
        "scenario": point.name,
        "scenario_hash": point.hash,
        "seed": point.seed,
        "status": status,
        "reason": reason,
        "wall_s": wall_s,
        "run_dir": run_dir,
        "passed": all(o.get("pass") for o in outcomes) if metrics else None,
        **{PARAM_PREFIX + k: v for k, v in point.params.items()},
        **(flatten(metrics) if metrics else {}),
    }


def read(directory: Path) -> list[dict]:
    """The rows of a sweep directory's table ([] when there is none yet)."""
    path = Path(directory) / PARQUET
    if not path.exists():
        return []
    import pyarrow.parquet as pq

    try:
        return pq.read_table(path).to_pylist()
    except Exception as exc:  # pyarrow raises several types for a damaged file
        raise ValueError(f"{path}: cannot read the results table: {exc}") from None


def columns(rows: Iterable[dict]) -> list[str]:
    """Identity first, then parameters, then metrics, each in order of first appearance."""
    seen: dict[str, None] = dict.fromkeys(IDENTITY)
    params: dict[str, None] = {}
    metrics: dict[str, None] = {}
    for r in rows:
        for key in r:
            if key not in seen:
                (params if key.startswith(PARAM_PREFIX) else metrics).setdefault(key)
    return [*seen, *params, *metrics]


def write(directory: Path, rows: list[dict]) -> None:
    """results.parquet and results.csv of `rows`, each written atomically."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    names = columns(rows)
    arrays = [_array(pa, [r.get(name) for r in rows]) for name in names]
    table = pa.Table.from_arrays(arrays, names=names)
    with atomic_path(Path(directory) / PARQUET) as tmp:
        pq.write_table(table, tmp)
    with atomic_path(Path(directory) / CSV) as tmp, open(tmp, "w", newline="") as handle:
        out = csv.writer(handle)
        out.writerow(names)
        out.writerows([_csv_cell(r.get(name)) for name in names] for r in rows)


def _array(pa, values: list):
    """A typed Arrow column: bool, int64, float64 or string (lists and tables as JSON text), nulls kept."""
    present = [v for v in values if v is not None]
    if present and all(isinstance(v, bool) for v in present):
        return pa.array(values, pa.bool_())
    if present and all(isinstance(v, int) and not isinstance(v, bool) for v in present):
        return pa.array(values, pa.int64())
    if present and all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in present):
        return pa.array([None if v is None else float(v) for v in values], pa.float64())
    if not present:
        return pa.array(values, pa.float64())
    return pa.array([None if v is None else v if isinstance(v, str) else json.dumps(v) for v in values], pa.string())


def _csv_cell(value) -> str:
    """Floats in their shortest exact form, empty for null, lists and tables as JSON."""
    if value is None:
        return ""
    if isinstance(value, (dict, list)):
        return json.dumps(value)
    return repr(value) if isinstance(value, float) else str(value)
