"""Why each estimator refused fixes: the run report's count of refused fixes by the rule that refused them (gps.csv's
`<id>.rule`, fusion.Verdict.rule), split into false alarms and caught faults, so a run shows which test of a monitor
refuses the good fixes its false-alarm rate counts."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from fusion.observation import POSITION_QUALITIES
from scenarios.report.document import Cell, Heading, Table, share
from scenarios.score.metrics import FAULT_M


@dataclass(frozen=True)
class RuleCount:
    """The measured fixes one rule refused: those within FAULT_M of what the environment added (false alarms) and those
    beyond it (faults caught); without the truth (a replay) only `refused` is known."""

    rule: str
    refused: int
    false_alarms: int | None
    caught: int | None


def rules_of(gps: dict[str, np.ndarray], eid: str) -> np.ndarray | None:
    """gps.csv's `<id>.rule` column as strings ("" where trusted; a column of empty cells reads as NaN), None without it."""
    rules = gps.get(f"{eid}.rule")
    if rules is None or rules.dtype.kind == "U":
        return rules
    return np.full(len(rules), "") if np.isnan(rules).all() else None


def by_rule(gps: dict[str, np.ndarray], eid: str) -> tuple[list[RuleCount], int | None]:
    """The measured fixes `eid` refused, counted by rule (most false alarms first), and how many measured fixes were
    good (the false-alarm rate's denominator; None without the truth). Empty without the rule column."""
    rules, trusted, quality = rules_of(gps, eid), gps.get(f"{eid}.trusted"), gps.get("quality")
    if rules is None or trusted is None or quality is None:
        return [], None
    measured = np.isin(quality, sorted(POSITION_QUALITIES))
    refused = measured & (trusted == 0)
    added = gps.get("added_err_h")
    faulty = None if added is None or added.dtype.kind != "f" else added > FAULT_M
    counts = []
    for rule in sorted(set(rules[refused].tolist())):
        mine = refused & (rules == rule)
        fa = None if faulty is None else int((mine & ~faulty).sum())
        caught = None if faulty is None else int((mine & faulty).sum())
        counts.append(RuleCount(rule or "unnamed", int(mine.sum()), fa, caught))
    counts.sort(key=lambda c: (-(c.false_alarms if c.false_alarms is not None else c.refused), c.rule))
    good = None if faulty is None else int((measured & ~faulty).sum())
    return counts, good


def refusals(gps: dict[str, np.ndarray], eids: list[str]) -> list:
    """The report's block: a row per (estimator, rule) that refused a measured fix (none refused: no block)."""
    rows = []
    for eid in eids:
        counts, good = by_rule(gps, eid)
        for c in counts:
            fa_share = None if c.false_alarms is None or not good else c.false_alarms / good
            rows.append(
                [
                    Cell(eid),
                    Cell(c.rule, css="text"),
                    Cell(str(c.refused)),
                    Cell("–" if c.false_alarms is None else f"{c.false_alarms} ({share(fa_share)})"),
                    Cell("–" if c.caught is None else str(c.caught)),
                ]
            )
    if not rows:
        return []
    note = (
        f"Measured fixes each estimator refused, by the rule that refused them (gps.csv's <id>.rule; a+b: both members of "
        f"a combined monitor refused): false alarms, the fixes the environment moved by {FAULT_M:g} m or less, with their "
        f"share of all such fixes (the rules' shares add up to the false-alarm rate above); caught, those it moved more."
    )
    return [Heading(3, "Why fixes were refused"), Table(["estimator", "rule", "refused", "false alarms", "caught"], rows, note)]
