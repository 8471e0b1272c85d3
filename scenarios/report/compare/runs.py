"""Finding and reading run directories, and the suite.json and sweep results listing runs that left none."""

from __future__ import annotations

import json
import os
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from scenarios.report.document import NULL


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


def plural(n: int, word: str) -> str:
    """'1 run', '3 runs'."""
    return f"{n} {word}{'' if n == 1 else 's'}"


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
            elif "sweep.json" in files and ("results.parquet" in files or "results.csv" in files):
                listings.append(Path(root) / ("results.parquet" if "results.parquet" in files else "results.csv"))
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
    return RunInfo(
        path,
        str(run.get("scenario") or config.get("name") or path.name),
        seed if isinstance(seed, int) else None,
        str(run.get("scenario_hash") or ""),
        config,
        metrics,
    )


def _read(file: Path, parse: Callable[[str], object], what: str, kind: type):
    """A parsed file, or ValueError in one line naming it."""
    try:
        tree = parse(file.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:  # JSONDecodeError and TOMLDecodeError are ValueErrors
        raise ValueError(f"{file}: unreadable {what} ({' '.join(str(exc).split())})") from None
    if not isinstance(tree, kind):
        raise ValueError(f"{file}: not the expected {what} {'object' if kind is dict else 'list'}")
    return tree


def unfinished(listings: list[Path]) -> list[Unfinished]:
    """The suite cases and sweep runs that failed (they left no run directory to compare)."""
    out = []
    for f in listings:
        if f.name in ("results.parquet", "results.csv"):
            from scenarios.batch import table as sweep_table

            out += [
                Unfinished(f"{r['scenario']} (seed {r['seed']})", str(r.get("reason") or r["status"]), f)
                for r in sweep_table.read(f.parent)
                if r.get("status") != "ok"
            ]
        else:
            out += [
                Unfinished(str(case.get("name", NULL)) + (f" (seed {case['seed']})" if case.get("seed") is not None else ""), str(case["error"]), f)
                for case in suite_cases(f)
                if isinstance(case, dict) and case.get("error")
            ]
    return out


def suite_cases(path: Path) -> list:
    """The cases of a suite.json: {"cases": [...], ...}, or the bare list older suites wrote."""
    tree = _read(path, json.loads, "JSON", (dict, list))
    cases = tree.get("cases") if isinstance(tree, dict) else tree
    if not isinstance(cases, list):
        raise ValueError(f"{path}: no list of cases")
    return cases
