"""Run an external component's command: in its own process group and working folder, stdout and stderr kept in files,
ended on timeout, Ctrl-C or SIGTERM of the bench, its own wall time, CPU time and peak memory measured apart from the
bench's.

The command is waited for with wait4, whose CPU time is the command's and its waited-for descendants' alone (not the
bench's matcher workers'). Its ru_maxrss is not the command's own: Linux carries the high-water mark of the memory the
child had before exec, a copy of the bench's (250 MB for `sh -c 'exit 3'`), into it. So the peak memory is read from
/proc instead: the largest VmHWM (peak resident set) of the processes of its group, sampled as it runs (a process
that lives less than a sampling period can be missed; it rarely is the largest). A timeout or an interrupt ends the
whole group: SIGTERM, then SIGKILL after a grace period; an interrupt is raised again once the group is gone, so the run
unwinds as it does for Ctrl-C.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

GRACE_S = 3.0
"""How long a command has after SIGTERM to end before its group gets SIGKILL, s."""
POLL_S = 0.05
"""How often the wait looks at the command and samples its group's memory, s."""
PROC = Path("/proc")


@dataclass(frozen=True)
class Finished:
    """A command that ended: its exit code (negative: the signal that ended it), whether the bench ended it for
    overrunning its timeout, its wall time (s), CPU time (user + system, s, its descendants' included) and peak resident
    memory (MB, its group's largest process's, sampled; NaN where there is no /proc)."""

    exit_code: int
    timed_out: bool
    wall_s: float
    cpu_s: float
    peak_rss_mb: float

    def measures(self) -> dict:
        """The numbers metrics.json records under the component's `external`."""
        return {"exit_code": self.exit_code, "wall_s": self.wall_s, "cpu_s": self.cpu_s, "peak_rss_mb": self.peak_rss_mb}


def executable(word: str) -> str:
    """The absolute path of the command's first word (a name on PATH, or a path); a ValueError naming it when none."""
    if os.sep in word:
        path = os.path.abspath(word)  # not resolved: a venv's python is a symbolic link that must stay one
        if os.path.isfile(path) and os.access(path, os.X_OK):
            return path
        raise ValueError(f"command: {word}: no such executable file")
    found = shutil.which(word)
    if found is None:
        raise ValueError(f"command: {word}: not found on PATH")
    return found


def wrapped(words: list[str]) -> int | None:
    """Where in a command line starting with `env NAME=VALUE ...` the program it runs is (the first word after env's
    assignments and options), or None when it does not start with env: that word is checked and resolved as the first."""
    if not words or os.path.basename(words[0]) != "env":
        return None
    i = 1
    while i < len(words) and (words[i].startswith("-") or "=" in words[i]):
        i += 1
    return i if i < len(words) else None


def run(argv: list[str], workdir: Path, env: dict[str, str], timeout_s: float, stdout: Path, stderr: Path) -> Finished:
    """Run `argv` in `workdir` with the bench's environment and `env`, its output streams into `stdout` and `stderr`."""
    with open(stdout, "wb") as out, open(stderr, "wb") as err:
        start = time.perf_counter()
        process = subprocess.Popen(
            argv, cwd=workdir, env={**os.environ, **env}, stdin=subprocess.DEVNULL, stdout=out, stderr=err, start_new_session=True
        )
        try:
            status, usage, timed_out, peak_kib = _wait(process, start + timeout_s)
        except BaseException:  # Ctrl-C or SIGTERM of the bench (riverbench.signals): the group goes with it
            if process.returncode is None:
                _end(process)
            raise
        wall = time.perf_counter() - start
    _signal_group(process.pid, signal.SIGKILL)  # what it left running in its group
    return Finished(
        exit_code=os.waitstatus_to_exitcode(status),
        timed_out=timed_out,
        wall_s=wall,
        cpu_s=usage.ru_utime + usage.ru_stime,
        peak_rss_mb=peak_kib / 1024.0 if PROC.is_dir() else float("nan"),
    )


def _wait(process: subprocess.Popen, deadline: float) -> tuple[int, os.struct_rusage, bool, int]:
    """Wait for the command until `deadline` (perf_counter), then end its group; its status, usage, whether it overran
    and the largest peak resident set (KiB) of its group's processes."""
    peak = 0
    while True:
        peak = max(peak, group_peak_kib(process.pid))
        pid, status, usage = os.wait4(process.pid, os.WNOHANG)
        if pid:
            process.returncode = os.waitstatus_to_exitcode(status)  # reaped here: Popen must not wait for it again
            return status, usage, False, peak
        if time.perf_counter() >= deadline:
            status, usage = _end(process)
            return status, usage, True, peak
        time.sleep(POLL_S)


def group_peak_kib(pgid: int) -> int:
    """The largest VmHWM (KiB) among the live processes of process group `pgid` (0 when none can be read)."""
    peak = 0
    for entry in PROC.glob("[0-9]*") if PROC.is_dir() else ():
        try:
            stat = (entry / "stat").read_text()
            if int(stat.rpartition(")")[2].split()[2]) != pgid:  # fields after the command name: state, ppid, pgrp
                continue
            for line in (entry / "status").read_text().splitlines():
                if line.startswith("VmHWM:"):
                    peak = max(peak, int(line.split()[1]))
        except (OSError, ValueError, IndexError):
            continue  # gone meanwhile, or not ours to read
    return peak


def _end(process: subprocess.Popen) -> tuple[int, os.struct_rusage]:
    """End the command's process group (SIGTERM, then SIGKILL after GRACE_S) and reap the command."""
    _signal_group(process.pid, signal.SIGTERM)
    deadline = time.perf_counter() + GRACE_S
    while time.perf_counter() < deadline:
        pid, status, usage = os.wait4(process.pid, os.WNOHANG)
        if pid:
            break
        time.sleep(POLL_S)
    else:
        _signal_group(process.pid, signal.SIGKILL)
        pid, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    _signal_group(process.pid, signal.SIGKILL)
    return status, usage


def _signal_group(pgid: int, sig: int) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):  # the group is gone already
        os.killpg(pgid, sig)
