"""How a batch of runs (a suite, a sweep) ended, with the two kinds of failure told apart: runs that failed to run
(a crash, a time-out, a stretch outside the route) and runs that ran but failed an expectation.

Both make the command exit 1; each is one line ("3 of 12 runs failed an expectation: ...").
"""

from __future__ import annotations

from dataclasses import dataclass

NAMED = 5
"""Runs named in a line; the rest are counted."""


@dataclass(frozen=True)
class BatchOutcome:
    """The labels of the runs that failed an expectation and of those that failed to run, out of `total`."""

    total: int
    failed_expectation: tuple[str, ...] = ()
    failed_to_run: tuple[str, ...] = ()

    @property
    def passed(self) -> bool:
        return not self.failed_expectation and not self.failed_to_run

    @property
    def exit_code(self) -> int:
        """0 when every run ran and passed every expectation, else 1."""
        return 0 if self.passed else 1

    def lines(self) -> list[str]:
        """One line per kind of failure, or one saying that every run passed."""
        if self.passed:
            return [f"{self.total} of {self.total} runs passed every expectation"]
        out = []
        if self.failed_expectation:
            out.append(f"{len(self.failed_expectation)} of {self.total} runs failed an expectation: {_names(self.failed_expectation)}")
        if self.failed_to_run:
            out.append(f"{len(self.failed_to_run)} of {self.total} runs failed to run: {_names(self.failed_to_run)}")
        return out


def _names(labels: tuple[str, ...]) -> str:
    shown = ", ".join(labels[:NAMED])
    return shown + (f" and {len(labels) - NAMED} more" if len(labels) > NAMED else "")


def of_cases(cases: list) -> BatchOutcome:
    """A suite's outcome from its CaseResults (`error`: failed to run; else `passed`)."""
    return BatchOutcome(
        len(cases),
        tuple(c.label for c in cases if not c.error and not c.passed),
        tuple(c.label for c in cases if c.error),
    )


def of_rows(rows: list[dict]) -> BatchOutcome:
    """A sweep's outcome from its table rows (status 'failed': failed to run; `passed` False: failed an expectation)."""
    return BatchOutcome(
        len(rows),
        tuple(row_label(r) for r in rows if r["status"] == "ok" and r.get("passed") is False),
        tuple(row_label(r) for r in rows if r["status"] != "ok"),
    )


def row_label(row: dict) -> str:
    """'canal_multipath seed 1 lidar.range_noise_m=0.02': a sweep row as a reader finds it in the table."""
    params = " ".join(f"{k.removeprefix('param.')}={_short(v)}" for k, v in row.items() if k.startswith("param."))
    return f"{row['scenario']} seed {row['seed']}" + (f" {params}" if params else "")


def _short(value) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)
