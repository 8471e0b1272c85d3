"""A rich progress bar for a run: simulated time, scans and speed against real time."""

from __future__ import annotations

import time

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn


class RunProgress:
    """Context manager; `update(t, t_start, t_end, scans)` is the runner's progress callback. The speed is the recording
    or simulated time since the first update over the wall time since it (what was loaded or read before is not in it)."""

    def __init__(self, name: str, console: Console, quiet: bool = False) -> None:
        self.quiet = quiet
        self._last = 0.0
        self._first: tuple[float, float] | None = None  # (t, wall time) of the first update
        self._bar = Progress(
            TextColumn(f"[bold]{name}[/]"),
            BarColumn(),
            TextColumn("{task.fields[sim]}"),
            TextColumn("{task.fields[scans]} scans"),
            TextColumn("[cyan]{task.fields[speed]}"),
            TimeElapsedColumn(),
            TextColumn("eta"),
            TimeRemainingColumn(),
            console=console,
            transient=False,
            disable=quiet,
        )
        self._task = self._bar.add_task(name, total=1.0, sim="", scans=0, speed="")

    def update(self, t: float, t_start: float, t_end: float, scans: int) -> None:
        now = time.perf_counter()
        if self._first is None:
            self._first = (t, now)
        if now - self._last < 0.1 and t < t_end:
            return
        self._last = now
        done = t - t_start
        digits = 1 if t_end - t_start < 100 else 0  # a real capture may last 1.5 s
        speed = (t - self._first[0]) / (now - self._first[1]) if now > self._first[1] else 0.0
        self._bar.update(
            self._task,
            total=t_end - t_start,
            completed=done,
            scans=scans,
            sim=f"{done:,.{digits}f}/{t_end - t_start:,.{digits}f} s",
            speed=f"{speed:.1f}x real time",
        )

    def __enter__(self) -> RunProgress:
        self._bar.start()
        return self

    def __exit__(self, *exc) -> None:
        self._bar.stop()
