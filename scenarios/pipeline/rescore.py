"""`score(run_dir, name, file, contract)`: a trajectory made outside the bench scored into a finished run directory as if
its component had run inside (`riverbench score`).

The run directory gives everything the score needs: the scan times and the truth (groundtruth.tum), the
GPS-degradation windows (windows.csv), the run's clock, epoch and LiDAR mount (scenario.toml). The trajectory is read
and checked (scenarios.score.external), laid onto the scans (scenarios.score.anchoring) and scored by the very functions
a run's components are (scenarios.score.metrics: an estimator's estimate_metrics for anchor `map`, a matcher's
odometry_metrics otherwise), plus `coverage` (the share of the run's scans that got a pose) and `source` (the file and
the contract). metrics.json gets the node and the scenario's expectations and goals judged again; <name>.tum (at the
scans, waterline, UNIX time, as a run writes its own), windows.csv (an estimator's passages) and the report are
rewritten. Every check comes before anything is written; the files are written into a copy of the directory, whose new
and changed files then replace the run's (with Ctrl-C and SIGTERM held), so an error or an interrupt leaves the run as it was.
"""

from __future__ import annotations

import csv
import hashlib
import json
import os
import re
import secrets
import shutil
import signal
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

import scenarios
from riverbench.unixtime import on_ns_grid, unix_ns
from scenarios.pipeline import files
from scenarios.score import anchoring, external, metrics, units
from scenarios.score import windows as win
from scenarios.score.expectations import Outcome
from scenarios.score.external import Contract, Span
from scenarios.spec.scenario import ID_PATTERN, Scenario
from sim.trajectory import mount_matrix

SECTIONS = ("estimators", "matchers")
TREE_ORDER = ("provenance", "run", "gps", "vessel", "estimators", "matchers", "compass", "expectations", "goals", "units")
"""metrics.json's top-level keys in the order a run writes them (others kept after them)."""


@dataclass(frozen=True)
class FinishedRun:
    """A finished run directory as a score reads it: its scenario and metrics tree, the scan times (s, run clock) with the
    true base_link poses there (at the waterline, as groundtruth.tum holds them), its GPS-degradation windows, the span
    its stamps must lie in and the LiDAR mount (base_link<-lidar)."""

    path: Path
    scenario: Scenario
    metrics: dict
    scan_t: np.ndarray
    truth: np.ndarray
    windows: list[win.Window]
    span: Span
    mount: np.ndarray

    @classmethod
    def open(cls, path: Path) -> FinishedRun:
        """Read the run directory `path`; one line when it is not a finished simulated run."""
        path = Path(path).resolve()
        if not path.is_dir():
            raise ValueError(f"{path}: no such run directory")
        for needed in ("metrics.json", "scenario.toml", "windows.csv"):
            if not (path / needed).is_file():
                raise ValueError(f"{path}: no {needed}, not a finished run directory (what `riverbench run` writes)")
        if not (path / "groundtruth.tum").is_file():
            raise ValueError(f"{path}: no groundtruth.tum, so no truth to score against (a replay has none)")
        return cls.read(path, scenarios.load(path / "scenario.toml"), json.loads((path / "metrics.json").read_text()))

    @classmethod
    def read(cls, path: Path, scenario: Scenario, tree: dict) -> FinishedRun:
        """The run directory `path` of `scenario` with the metrics tree `tree` (a run scoring its command components
        before it writes metrics.json): its truth and windows read from groundtruth.tum and windows.csv."""
        rows = files.read_tum(path / "groundtruth.tum", scenario_time=True)
        truth = np.tile(np.eye(4), (len(rows), 1, 1))
        truth[:, :3, :3] = Rotation.from_quat(rows[:, 4:8]).as_matrix()
        truth[:, :3, 3] = rows[:, 1:4]
        revolution = 1.0 / scenario.lidar.rate_hz
        t_end = tree.get("run", {}).get("t_end")
        span = Span(
            t_first=float(rows[0, 0]) if len(rows) else 0.0,
            t_end=float(t_end) if t_end is not None else float(rows[-1, 0]) + revolution,
            zero_ns=unix_ns(scenario.gnss.epoch_utc),
            tolerance_s=anchoring.SCAN_TOLERANCE * revolution,
        )
        return cls(path, scenario, tree, rows[:, 0], truth, read_windows(path / "windows.csv"), span, mount_matrix(scenario.vessel))

    def check_name(self, name: str, replace: bool) -> None:
        """NAME must be an id (as a scenario's) that no component of the run has, unless it was scored in and `replace`."""
        if not re.match(ID_PATTERN, name) or name == "groundtruth":
            raise ValueError(f"NAME {name!r}: not a component id (a letter or _, then letters, digits or _; not 'groundtruth')")
        for section in SECTIONS:
            node = self.metrics.get(section, {}).get(name)
            if node is None:
                continue
            what = f"the run already has a{'n' if section == 'estimators' else ''} {section[:-1]} {name!r}"
            if "source" not in node:
                raise ValueError(f"NAME {name!r}: {what}, built in; choose another NAME")
            if not replace:
                raise ValueError(f"NAME {name!r}: {what}, scored from {node['source'].get('file')}; give --replace to score it again")


@dataclass(frozen=True)
class Scored:
    """A trajectory scored into a run: the run directory, the component's name, its section of metrics.json and node,
    and the scenario's expectations judged again."""

    run_dir: Path
    name: str
    section: str
    node: dict
    outcomes: list[Outcome]

    @property
    def passed(self) -> bool:
        return all(o.passed for o in self.outcomes)


def read_windows(path: Path) -> list[win.Window]:
    """windows.csv's windows, their bounds put back on the nanosecond grid the run's times lie on."""
    with open(path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    return [win.Window(r["kind"], float(on_ns_grid(float(r["start"]))), float(on_ns_grid(float(r["end"])))) for r in rows]


def score(run_dir: Path, name: str, file: Path, contract: Contract, *, replace: bool = False, report: bool = True) -> Scored:
    """Score the trajectory `file` under `contract` into the run directory as component `name` (see the module docstring);
    bad input is a ValueError of one line, with nothing written."""
    run = FinishedRun.open(run_dir)
    run.check_name(name, replace)
    count, placed = laid(run, file, contract)
    node = measured(run, placed, contract.section) | {"source": source(file, contract, count)}
    node = units.rounded(metrics.json_safe({contract.section: {name: node}}))[contract.section][name]
    tree, outcomes = judged(run, name, contract.section, node)
    with staged(run.path) as tmp:
        (tmp / "metrics.json").write_text(json.dumps(tree, indent=2) + "\n")
        files.write_tum(tmp / f"{name}.tum", run.scan_t, files.waterline(placed), run.span.zero_ns)
        error = metrics.horizontal_error(placed, run.truth) if contract.section == "estimators" else None
        rewrite_windows_csv(tmp / "windows.csv", run, name, error)
        if report:
            from scenarios.report import run_report

            run_report.write(tmp, scenario=run.scenario)
    return Scored(run.path, name, contract.section, node, outcomes)


def laid(run: FinishedRun, file: Path, contract: Contract) -> tuple[int, np.ndarray]:
    """The trajectory `file` read and checked under `contract` (ValueError: one line) and laid onto the run's scans
    (NaN: a scan without a pose); with the number of poses it holds."""
    trajectory = external.read(file, contract)
    t = external.on_run_clock(trajectory, file, contract.clock, run.span)
    poses = anchoring.to_base_link(trajectory.poses, contract.frame, run.mount)
    return len(poses), anchoring.anchored(anchoring.on_scans(t, poses, run.scan_t, run.span.tolerance_s), run.truth, contract.anchor)


def measured(run: FinishedRun, placed: np.ndarray, section: str) -> dict:
    """The metrics of poses laid onto the run's scans (NaN: none), as an estimator's or a matcher's, and their coverage."""
    if section == "estimators":
        node = metrics.estimate_metrics(placed, run.truth, run.scan_t, run.windows)
    else:
        node = metrics.odometry_metrics(placed, run.truth)
    have = np.isfinite(placed).all(axis=(1, 2))
    return node | {"coverage": float(have.mean()) if len(have) else float("nan")}


def judged(run: FinishedRun, name: str, section: str, node: dict) -> tuple[dict, list[Outcome]]:
    """The run's metrics tree with `node` as `section`.`name` (in place of any earlier one of that name) and the scenario's
    expectations and goals judged on it again; with the expectations' outcomes."""
    tree = run.metrics | {s: {k: v for k, v in run.metrics.get(s, {}).items() if k != name} for s in SECTIONS}
    tree[section][name] = node
    outcomes = [e.check(tree) for e in run.scenario.expectations()]
    goals = [o.as_goal() for o in (g.check(tree) for g in run.scenario.goal_checks())]
    return metrics.json_safe(ordered(tree | {"expectations": [o.as_dict() for o in outcomes], "goals": goals})), outcomes


def source(file: Path, contract: Contract, poses: int) -> dict:
    """metrics.json's `source` of a scored-in component: the file (absolute path, SHA-256), the contract and its pose count."""
    return {
        "file": str(Path(file).resolve()),
        "sha256": hashlib.sha256(Path(file).read_bytes()).hexdigest(),
        **{k: str(v) for k, v in contract.model_dump().items() if v is not None},
        "poses": poses,
    }


def ordered(tree: dict) -> dict:
    """The tree with its top-level keys in a run's order."""
    return {**{k: tree[k] for k in TREE_ORDER if k in tree}, **{k: v for k, v in tree.items() if k not in TREE_ORDER}}


def rewrite_windows_csv(path: Path, run: FinishedRun, name: str, error: np.ndarray | None) -> None:
    """windows.csv without `name`'s columns and, given its horizontal `error` at the scans (an estimator), with its passages."""
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    header, body = rows[0], rows[1:]
    keep = [i for i, column in enumerate(header) if not column.startswith(f"{name}.")]
    added = [f"{name}.{k}" for k in files.PASSAGE_KEYS] if error is not None else []
    with open(path, "w", newline="") as handle:
        w = csv.writer(handle)
        w.writerow([header[i] for i in keep] + added)
        for row, window in zip(body, run.windows):
            cells = [] if error is None else files.passage_cells(window, run.scan_t, error, win.next_start(window, run.windows))
            w.writerow([row[i] for i in keep] + cells)


@contextmanager
def staged(run_dir: Path) -> Iterator[Path]:
    """A copy of the run directory to write into; when the block succeeds, each file it added or changed is renamed over
    the run's own (with SIGINT and SIGTERM held, so an interrupt never leaves part of them), the directory itself staying
    (a shell inside it stays there). On an error or an interrupt the copy is removed and the run is as it was."""
    tmp = run_dir.parent / f".{run_dir.name}.score-{secrets.token_hex(6)}"
    shutil.copytree(run_dir, tmp, symlinks=True)
    try:
        yield tmp
        changed = [p.relative_to(tmp) for p in sorted(tmp.rglob("*")) if p.is_file() and not _same(p, run_dir / p.relative_to(tmp))]
        with held_signals():
            for relative in changed:
                (run_dir / relative).parent.mkdir(parents=True, exist_ok=True)
                os.replace(tmp / relative, run_dir / relative)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _same(path: Path, other: Path) -> bool:
    """Whether `other` is a file with the bytes of `path`."""
    return other.is_file() and other.stat().st_size == path.stat().st_size and other.read_bytes() == path.read_bytes()


@contextmanager
def held_signals() -> Iterator[None]:
    """SIGINT and SIGTERM held back (delivered when the block ends) where the platform can hold them."""
    mask = getattr(signal, "pthread_sigmask", None)
    if mask is None:
        yield
        return
    previous = mask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        mask(signal.SIG_SETMASK, previous)
