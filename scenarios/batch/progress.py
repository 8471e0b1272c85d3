"""What `riverbench sweep` shows: a progress bar over runs with its ETA, and the summary at the end."""

from __future__ import annotations

from pathlib import Path

from rich import box
from rich.console import Console, Group
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn
from rich.table import Table
from rich.text import Text

from scenarios.batch import outcome
from scenarios.batch.plan import SweepPlan
from scenarios.batch.sweep import SweepResult, rank

TOP = 5
"""Parameter combinations listed in the summary."""


class SweepProgress:
    """Context manager; start(to_run, skipped) and row(row) are run_sweep's callbacks."""

    def __init__(self, console: Console, quiet: bool = False) -> None:
        self.quiet = quiet
        self.failed_to_run = 0
        self.failed_expectation = 0
        self._bar = Progress(
            TextColumn("[bold]sweep[/]"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("runs"),
            TextColumn("{task.fields[failed]}"),
            TimeElapsedColumn(),
            TextColumn("eta"),
            TimeRemainingColumn(),
            console=console,
            disable=quiet,
        )
        self._task = self._bar.add_task("sweep", total=None, failed="")

    def start(self, to_run: int, skipped: int) -> None:
        if skipped and not self.quiet:
            self._bar.console.print(f"{skipped} run(s) already in the table: skipped", highlight=False)
        self._bar.update(self._task, total=to_run)

    def row(self, row: dict) -> None:
        """A line per finished run: pass, FAIL (expectations) or failed to run (why); the bar counts both failures."""
        ran = row["status"] == "ok"
        self.failed_to_run += not ran
        self.failed_expectation += ran and row.get("passed") is False
        if not self.quiet:
            label = escape(outcome.row_label(row))
            if not ran:
                line = f"[bold red]failed to run[/] {label} ({row['wall_s']:.0f} s): {escape(str(row['reason']))}"
            elif row.get("passed") is False:
                failed = row.get("expectations.failed", 0)
                of = failed + row.get("expectations.passed", 0)
                line = f"[bold red]FAIL[/] {label} ({row['wall_s']:.0f} s): {failed} of {of} expectations failed"
            else:
                line = f"[green]pass[/] {label} ({row['wall_s']:.0f} s)"
            self._bar.console.print(line, highlight=False)
        counts = [f"{n} {what}" for n, what in ((self.failed_expectation, "failed an expectation"), (self.failed_to_run, "failed to run")) if n]
        self._bar.update(self._task, advance=1, failed=f"[red]{', '.join(counts)}[/]" if counts else "")

    def __enter__(self) -> SweepProgress:
        self._bar.start()
        return self

    def __exit__(self, *exc) -> None:
        self._bar.stop()


def summary(result: SweepResult, plan: SweepPlan, objective: str | None, minimize: bool, plots: list[Path]) -> Group:
    """Counts, failures, the best parameter combinations by the objective, and where the table and plots are."""
    parts: list = [Text(f"{len(result.rows)} runs in the table: {result.ran} run now, {result.skipped} already done")]
    parts += [Text(line) for line in outcome.of_rows(result.rows).lines()]
    if result.failed:
        failures = Table(title="runs that failed to run", box=box.SIMPLE_HEAD)
        for col in ("scenario", "seed", "reason"):
            failures.add_column(col, overflow="fold")
        for r in result.failed[:TOP]:
            failures.add_row(r["scenario"], str(r["seed"]), r["reason"])
        parts.append(failures)
    if objective:
        ranked = rank(result.rows, objective, minimize)
        best = Table(title=f"best by {objective} ({'lowest' if minimize else 'highest'} median over seeds)", box=box.SIMPLE_HEAD)
        for col, justify in (("scenario", "left"), ("parameters", "left"), ("median", "right"), ("min .. max", "right"), ("seeds", "right")):
            best.add_column(col, justify=justify, overflow="fold")
        for g in ranked[:TOP]:
            best.add_row(
                g.scenario,
                ", ".join(f"{k}={_short(v)}" for k, v in g.params.items()) or "-",
                f"{g.median:.4g}",
                f"{min(g.values):.4g} .. {max(g.values):.4g}",
                str(len(g.values)),
            )
        parts.append(best if ranked else Text(f"no finished run has a value of {objective}"))
    parts.append(
        Text(f"table: {result.out_dir / 'results.csv'}" + (" (and results.parquet)" if (result.out_dir / "results.parquet").exists() else ""))
    )
    if plots:
        parts.append(Text(f"plots: {', '.join(str(p) for p in plots)}"))
    return Group(*parts)


def _short(value) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)
