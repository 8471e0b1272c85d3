"""A sweep's results table: one row per run, CSV, and Parquet beside it (typed, for pandas/polars) when pyarrow is
installed (`pip install 'riverbench[parquet]'`).

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
TEXT = ("scenario", "scenario_hash", "status", "reason", "run_dir")
"""Identity columns that are always text (a hash of digits only stays a string when read back from the CSV)."""


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

    walk({k: v for k, v in metrics.items() if k not in ("expectations", "provenance", "units")}, "")
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
    """The rows of a sweep directory's table ([] when there is none yet): from the Parquet file when there is one and
    pyarrow is installed, else from the CSV (cells typed back: empty -> None, True/False, integers, floats, text)."""
    parquet, text = Path(directory) / PARQUET, Path(directory) / CSV
    if parquet.exists() and _pyarrow() is not None:
        import pyarrow.parquet as pq

        try:
            return pq.read_table(parquet).to_pylist()
        except Exception as exc:  # pyarrow raises several types for a damaged file
            raise ValueError(f"{parquet}: cannot read the results table: {exc}") from None
    if not text.exists():
        return []
    try:
        with open(text, newline="", encoding="utf-8") as handle:
            return [{key: (cell or "") if key in TEXT else _typed(cell) for key, cell in r.items()} for r in csv.DictReader(handle)]
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise ValueError(f"{text}: cannot read the results table: {exc}") from None


def _pyarrow():
    """The pyarrow module, or None when the optional [parquet] extra is not installed."""
    try:
        import pyarrow
    except ImportError:
        return None
    return pyarrow


def _typed(cell: str | None):
    """A CSV cell back as what _csv_cell wrote: None, a bool, an int, a float (repr round-trips exactly) or text."""
    if cell is None or cell == "":
        return None
    if cell in ("True", "False"):
        return cell == "True"
    try:
        return int(cell)
    except ValueError:
        pass
    try:
        return float(cell)
    except ValueError:
        return cell


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
    """results.csv and (with pyarrow) results.parquet of `rows`, each written atomically."""
    names = columns(rows)
    pa = _pyarrow()
    if pa is not None:
        import pyarrow.parquet as pq

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
