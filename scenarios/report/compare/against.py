"""The comparison report's section against a stored baseline: what regressed, improved or changed, per scenario and metric."""

from __future__ import annotations

from riverbench.provenance import describe
from scenarios.report.document import NULL, Cell, Heading, Table, Text
from scenarios.score.regression import Comparison, MetricVerdict

CHANGED_ROWS = 200
"""Moved metrics without a direction listed on the page before it says how many more there are (all are in suite.json)."""


def section(comparison: Comparison) -> list:
    """Heading, verdict line, both sides' provenance, what could not be compared, and the table of moved metrics."""
    counts = comparison.counts()
    blocks = [
        Heading(2, "Against the baseline"),
        Text(f"{'REGRESSED' if comparison.failed else 'no regression'}: {comparison.sentence()}", "fail" if comparison.failed else "pass"),
        Text(f"baseline: {describe(comparison.base_provenance)}", "meta"),
        Text(f"now: {describe(comparison.now_provenance)}", "meta"),
        Text(
            "Each metric is compared seed by seed (the same seed runs the same world, noise and motion). A change is called "
            "when the median of the per-seed changes exceeds the larger of the metric family's tolerance and twice the "
            "standard error of the baseline's spread over seeds, and nearly all seeds moved the same way; one seed is enough "
            "for a crash or a collision. Metrics describing the simulated world and sensors have no better direction: they are "
            "'changed'. Wall-clock figures are shown but never fail the comparison.",
            "note",
        ),
    ]
    if comparison.failed_runs:
        blocks.append(
            Text(
                "Runs that failed now and not in the baseline: "
                + "; ".join(f"{name} seed {seed}: {why}" for name, failed in comparison.failed_runs.items() for seed, why in failed.items()),
                "fail",
            )
        )
    for label, names in (
        ("Scenarios not in the baseline (not compared)", comparison.new_scenarios),
        ("Scenarios in the baseline only (not run)", comparison.missing_scenarios),
        ("Scenarios whose resolved definition changed since the baseline", list(comparison.changed_scenarios)),
    ):
        if names:
            blocks.append(Text(f"{label}: {', '.join(names)}"))
    moved = [*comparison.by("regressed"), *comparison.by("improved"), *comparison.by("changed")[:CHANGED_ROWS]]
    if moved:
        more = len(comparison.by("changed")) - CHANGED_ROWS
        note = (
            f"{counts['unchanged']} metrics unchanged ({counts['identical']} bit-identical, {counts['moved_within_threshold']} moved "
            f"within their threshold)" + (f"; {more} more changed metrics are in suite.json" if more > 0 else "")
        )
        blocks.append(
            Table(
                ["scenario", "metric", "family", "baseline median [min–max]", "now median", "change", "threshold", "verdict"],
                [_row(v) for v in moved],
                note,
            )
        )
    return blocks


def _row(v: MetricVerdict) -> list[Cell]:
    row = v.as_dict()
    base = f"{_g(row['baseline_median'])} [{_g(row['baseline_min'])}–{_g(row['baseline_max'])}]"
    change = (
        NULL
        if row["change"] is None
        else f"{row['change']:+.4g}" + (f" ({row['change'] / abs(row['baseline_median']):+.0%})" if row["baseline_median"] else "")
    )
    css = {"regressed": "fail" if v.gating else "", "improved": "pass"}.get(v.verdict, "")
    verdict = v.verdict + ("" if v.gating else " (wall clock)")
    return [
        Cell(v.scenario, css="text"),
        Cell(v.metric, css="text"),
        Cell(v.family.name, css="text"),
        Cell(base),
        Cell(_g(row["now_median"])),
        Cell(change),
        Cell(_g(row["threshold"])),
        Cell(verdict, css=css or "text"),
    ]


def _g(value) -> str:
    return NULL if value is None else f"{value:.4g}"
