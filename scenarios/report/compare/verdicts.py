"""The written summary: who wins each criterion where, and whether by more than the spread over seeds."""

from __future__ import annotations

from dataclasses import dataclass, replace

from scenarios.report.compare.groups import (
    APE_ALIGNED,
    APE_P95,
    AVAILABLE,
    BLACKOUT,
    HZ,
    NLOS,
    SUCCESS,
    Configuration,
    Spread,
)
from scenarios.report.compare.runs import plural
from scenarios.report.document import Column

OPEN_WATER = "open_river"
"""The scenario whose results the summary calls open water."""
VERDICTS = {"clear": "a clear difference", "within": "within the spread: no clear winner", "unknown": "the spread is unknown (one seed)"}
TALLY_WORDS = {"clear": "clear", "within": "within the spread", "unknown": "with one seed"}
"""How the tally of wins words each verdict: 'clear in 2, within the spread in 1'."""


@dataclass(frozen=True)
class Criterion:
    """What the written summary compares: a phrase, the column whose medians it ranks, the unit after the numbers."""

    phrase: str
    column: Column
    unit: str
    kind: str  # "estimators" or "matchers"


@dataclass(frozen=True)
class Duel:
    """The best component of one criterion in one configuration, and the runner-up."""

    winner: str
    best: Spread
    runner_up: str
    second: Spread


CRITERIA = (
    Criterion("Lowest APE p95", APE_P95, " m", "estimators"),
    Criterion("Under bridges (worst error in blackout windows)", BLACKOUT, " m", "estimators"),
    Criterion("Beside walls and in canals (worst error in NLOS windows)", NLOS, " m", "estimators"),
    Criterion("Highest matching success", SUCCESS, "", "matchers"),
    Criterion("Lowest aligned APE rmse of the matcher odometry", APE_ALIGNED, " m", "matchers"),
    Criterion("Fastest matcher", HZ, " Hz", "matchers"),
)


def duel(nodes: dict[str, dict], column: Column) -> Duel | None:
    """The best and second-best component by median in this column (None with fewer than two values)."""
    scored = [(cid, node[column.title]) for cid, node in nodes.items() if node.get(column.title)]
    if len(scored) < 2:
        return None
    scored.sort(key=lambda item: item[1].median, reverse=column.better == "high")
    (winner, best), (runner_up, second) = scored[:2]
    return Duel(winner, best, runner_up, second)


def verdict(d: Duel, column: Column) -> str:
    """'tie' (equal as printed), 'unknown' (a single seed), 'clear' (the ranges over seeds do not overlap) or 'within'."""
    if column.fmt(d.best.median) == column.fmt(d.second.median):
        return "tie"
    if min(d.best.n, d.second.n) < 2:
        return "unknown"
    apart = d.best.hi < d.second.lo if column.better == "low" else d.best.lo > d.second.hi
    return "clear" if apart else "within"


def quote(s: Spread, criterion: Criterion, seeds: bool) -> str:
    """'2.80 m (2.60–3.10 over 3 seeds)': the median and its range over seeds."""
    fmt = criterion.column.fmt
    text = f"{fmt(s.median)}{criterion.unit}"
    if s.n < 2:
        return f"{text} (1 seed)"
    return f"{text} ({fmt(s.lo)}–{fmt(s.hi)}{f' over {s.n} seeds' if seeds else ''})"


def sentence(criterion: Criterion, d: Duel, nodes: dict[str, dict] | None = None) -> str:
    """One factual sentence: the winner against the runner-up, and whether the gap exceeds the spread over seeds; for
    estimators (given their `nodes`), how many of the scans each had an estimate on when either missed some."""
    v = verdict(d, criterion.column)
    coverage = availability(d, nodes) if criterion.kind == "estimators" and nodes else ""
    if v == "tie":
        return f"{criterion.phrase}: {d.winner} and {d.runner_up} tie at {criterion.column.fmt(d.best.median)}{criterion.unit}.{coverage}"
    return (
        f"{criterion.phrase}: {d.winner} {quote(d.best, criterion, True)} against {d.runner_up} "
        f"{quote(d.second, criterion, d.second.n != d.best.n)}: {VERDICTS[v]}.{coverage}"
    )


def availability(d: Duel, nodes: dict[str, dict]) -> str:
    """' Available (share of the scans with an estimate, the scans its errors cover): ekf 85.7 %, gps_only 99.9 %.' when
    either estimator lacked an estimate on some scans (a late start, a gap), else nothing."""
    texts = [AVAILABLE.fmt(s.median if (s := nodes.get(cid, {}).get(AVAILABLE.title)) else None) for cid in (d.winner, d.runner_up)]
    if all(t == AVAILABLE.fmt(1.0) for t in texts):
        return ""
    return f" Available (share of the scans with an estimate, the scans its errors cover): {d.winner} {texts[0]}, {d.runner_up} {texts[1]}."


def conf_sentences(conf: Configuration) -> list[str]:
    """Per criterion with two or more components to compare, who wins in this configuration."""
    return [sentence(c, d, getattr(conf, c.kind)) for c in CRITERIA if (d := duel(getattr(conf, c.kind), c.column))]


def tally(confs: list[Configuration], criterion: Criterion) -> str | None:
    """Which component wins the criterion in how many configurations, and how many of those wins are clear."""
    duels = [d for c in confs if (d := duel(getattr(c, criterion.kind), criterion.column))]
    if not duels:
        return None
    wins: dict[str, list[str]] = {}
    for d in duels:
        wins.setdefault(d.winner if verdict(d, criterion.column) != "tie" else "", []).append(verdict(d, criterion.column))
    ties = len(wins.pop("", []))
    parts = [
        f"{winner} in {len(codes)} of {plural(len(duels), 'configuration')} ("
        + ", ".join(f"{word} in {codes.count(code)}" for code, word in TALLY_WORDS.items() if code in codes)
        + ")"
        for winner, codes in sorted(wins.items(), key=lambda item: -len(item[1]))
    ]
    return f"{criterion.phrase}: " + "; ".join(parts + ([f"a tie in {ties}"] if ties else [])) + "."


def overall_sentences(confs: list[Configuration]) -> list[str]:
    """The summary over all configurations: wins per criterion, open water, failures."""
    out = [t for c in CRITERIA if (t := tally(confs, c))]
    for conf in (c for c in confs if c.scenario == OPEN_WATER):
        if d := duel(conf.estimators, APE_P95):
            out.append(sentence(replace(CRITERIA[0], phrase=f"Open water ({conf.title}), lowest APE p95"), d, conf.estimators))
    failures = [
        f"{cid} ({kind.removesuffix('s')}) in {node['failures']} of {plural(node['runs'], 'run')} of {conf.title}"
        for conf in confs
        for kind in ("estimators", "matchers")
        for cid, node in getattr(conf, kind).items()
        if node["failures"]
    ]
    out.append("Failed: " + "; ".join(failures) + "." if failures else "No estimator or matcher failed in any run.")
    return out
