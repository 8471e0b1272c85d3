"""A rich progress bar for a run: simulated time, scans and speed against real time."""

from __future__ import annotations

import time

from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn


class RunProgress:
    """Context manager; `update(t, t_start, t_end, scans)` is the runner's progress callback."""

    def __init__(self, name: str, console: Console, quiet: bool = False) -> None:
        self.quiet = quiet
        self._start = time.perf_counter()
        self._last = 0.0
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
        if now - self._last < 0.1 and t < t_end:
            return
        self._last = now
        done = t - t_start
        speed = done / (now - self._start) if now > self._start else 0.0
        self._bar.update(
            self._task,
            total=t_end - t_start,
            completed=done,
            scans=scans,
            sim=f"{done:,.0f}/{t_end - t_start:,.0f} s",
            speed=f"{speed:.1f}x real time",
        )

    def __enter__(self) -> RunProgress:
        self._bar.start()
        return self

    def __exit__(self, *exc) -> None:
        self._bar.stop()
