"""A run's command components (scenarios.spec.command): checked before anything runs, run on the cached recording once
the built-ins are done, their trajectories read back under the score contract and scored by the functions
`riverbench score` uses, into the metrics tree before the expectations are judged.

Each gets a working folder commands/<id>/ (with an empty out/ for {out}) and its stdout and stderr in
commands/<id>.stdout.log and .stderr.log. A command that exits non-zero, times out, writes no file, writes one that
fails a contract check or covers fewer scans than its min_coverage is a failed component: `failed` true, its one-line
`reason`, no metric (so an expectation on it fails, never passes on nothing), an entry in run.failures; the other
components are untouched. Under the component, `external` records what the command cost apart from the bench: exit
code, wall and CPU time, peak memory, and the recording (format, whether the cache had it, the seconds it took).
"""

from __future__ import annotations

import glob
import os
from pathlib import Path

import numpy as np

from scenarios.pipeline import command, files, recording_cache, rescore
from scenarios.pipeline.recording_cache import Recording
from scenarios.score import metrics, units
from scenarios.spec.command import FILLED, CommandSpec
from scenarios.spec.scenario import Scenario

FOLDER = "commands"
"""The run directory's folder of the commands' working folders and logs."""


def check(scenario: Scenario) -> None:
    """Every command's executable exists (a name on PATH or a path; with `env NAME=VALUE ... program`, the program too):
    else one line naming it, before anything runs."""
    for section, spec in scenario.commands:
        words = spec.argv({k: k for k in FILLED})
        try:
            command.executable(words[0])
            if (i := command.wrapped(words)) is not None:
                command.executable(words[i])
        except ValueError as exc:
            raise ValueError(f"{section}.{spec.id}.{exc}") from None


def recordings(scenario: Scenario) -> dict[str, Recording]:
    """The recording of each format the commands read, from the cache (written there first when it is not)."""
    return {fmt: recording_cache.get(scenario, fmt) for fmt in sorted({spec.recording for _, spec in scenario.commands})}


def score_into(scenario: Scenario, run_dir: Path, tree: dict, recorded: dict[str, Recording]) -> dict:
    """`tree` with each command component run and its node under its section; its <id>.tum and (an estimator's)
    windows.csv passages written into `run_dir`, which already holds the run's groundtruth.tum and windows.csv."""
    run = rescore.FinishedRun.read(Path(run_dir).resolve(), scenario, tree)
    tree = {**tree, "run": {**tree["run"], "failures": list(tree["run"].get("failures", []))}}
    for section, spec in scenario.commands:
        node = component(run, section, spec, recorded[spec.recording])
        tree[section] = {**tree.get(section, {}), spec.id: node}
        if node["failed"]:
            tree["run"]["failures"].append({"component": section[:-1], "id": spec.id, "stamp": None, "reason": node["reason"]})
    return tree


def component(run: rescore.FinishedRun, section: str, spec: CommandSpec, recording: Recording) -> dict:
    """Run one command component and score what it wrote: its metrics node (rounded as metrics.json shows it)."""
    workdir = run.path / FOLDER / spec.id
    (workdir / "out").mkdir(parents=True)
    values = {"recording": str(recording.path), "out": str(workdir / "out"), "workdir": str(workdir)}
    argv = spec.argv(values)
    argv[0] = command.executable(argv[0])
    if (i := command.wrapped(argv)) is not None:  # env NAME=VALUE ... program: the program as the bench found it
        argv[i] = command.executable(argv[i])
    logs = {s: run.path / FOLDER / f"{spec.id}.{s}.log" for s in ("stdout", "stderr")}
    finished = command.run(argv, workdir, spec.environment(values), spec.timeout_s, logs["stdout"], logs["stderr"])
    external = costs(finished, recording) | {"recording": spec.recording, "logs": [str(p.relative_to(run.path)) for p in logs.values()]}
    reason = ended_badly(finished, spec, logs["stderr"])
    if reason is None:
        try:
            file = one_file(workdir, spec.output, "output")
            times = str(one_file(workdir, spec.times, "times")) if spec.times is not None else None
            count, placed = rescore.laid(run, file, spec.contract(times))
            covered = float(np.isfinite(placed).all(axis=(1, 2)).mean()) if len(placed) else 0.0
            if covered < spec.min_coverage:
                raise ValueError(
                    f"{file}: {count} poses cover {covered:.1%} of the run's {len(placed)} scans, below min_coverage "
                    f"{spec.min_coverage:.0%} (dropped frames; a pose counts for the scan stamped within a quarter revolution)"
                )
        except ValueError as exc:
            reason = str(exc).replace(f"{run.path}{os.sep}", "")
    if reason is not None:
        return {"failed": True, "reason": reason, "external": external}
    external |= {"output": str(file.relative_to(run.path)), "poses": count}
    node = rescore.measured(run, placed, section) | {"failed": False, "external": external}
    node = units.rounded(metrics.json_safe({section: {spec.id: node}}))[section][spec.id]
    files.write_tum(run.path / f"{spec.id}.tum", run.scan_t, files.waterline(placed), run.span.zero_ns)
    if section == "estimators":
        rescore.rewrite_windows_csv(run.path / "windows.csv", run, spec.id, metrics.horizontal_error(placed, run.truth))
    return node


def costs(finished: command.Finished, recording: Recording) -> dict:
    """The numbers of a component's `external`: what its command and its recording cost."""
    return finished.measures() | {"recording_cached": recording.hit, "recording_s": recording.seconds}


def template(section: str) -> dict:
    """A scored command component's metrics node, every number NaN: the metric names a sweep's --objective and --plot
    accept for it before anything has run (scenarios.batch.sweep.metric_names)."""
    empty, nan = np.empty((0, 4, 4)), float("nan")
    if section == "estimators":
        node = metrics.estimate_metrics(empty, empty, np.empty(0), [])
    else:
        node = metrics.odometry_metrics(empty, empty)
    unmeasured = costs(command.Finished(0, False, nan, nan, nan), Recording(Path(), False, nan))
    return node | {"coverage": nan, "failed": False, "external": unmeasured | {"poses": 0}}


def ended_badly(finished: command.Finished, spec: CommandSpec, stderr: Path) -> str | None:
    """Why the command's run is a failure (a timeout, a non-zero exit), or None."""
    if finished.timed_out:
        return f"timed out after {spec.timeout_s:g} s (timeout_s) and was ended"
    if finished.exit_code != 0:
        how = f"was ended by signal {-finished.exit_code}" if finished.exit_code < 0 else f"exited with code {finished.exit_code}"
        last = last_line(stderr)
        return f"the command {how}" + (f"; its stderr ends: {last}" if last else "")
    return None


def last_line(path: Path) -> str:
    """The last non-blank line of a text file (at most 200 characters), '' when none."""
    lines = [line.strip() for line in path.read_text(errors="replace").splitlines() if line.strip()]
    return lines[-1][:200] if lines else ""


def one_file(workdir: Path, pattern: str, what: str) -> Path:
    """The one file `pattern` (a glob relative to `workdir`, symbolic links followed) matches; else one line saying so."""
    found = sorted({Path(p).resolve() for p in glob.glob(str(workdir / pattern), recursive=True) if Path(p).is_file()})
    if not found:
        raise ValueError(f"the command wrote no file matching {what} = {pattern!r} in its working folder")
    if len(found) > 1:
        names = ", ".join(str(p.relative_to(workdir.resolve())) for p in found[:3])
        raise ValueError(f"{what} = {pattern!r} matches {len(found)} files ({names}{', …' if len(found) > 3 else ''}): make it match one")
    return found[0]
