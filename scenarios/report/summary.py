"""One-screen summary tables of a run and of a suite (rich)."""

from __future__ import annotations

from rich import box
from rich.console import Group
from rich.table import Table


def _num(value, fmt: str = ".2f") -> str:
    return "–" if value is None else format(value, fmt)


def failed_components(metrics: dict) -> list[str]:
    """The components that failed during a run, as 'id at t s: reason' (metrics.json's run.failures); a run survives
    them, and its expectations may not mention them (a closed loop's autopilot then holds its course blind)."""
    return [f"{f.get('id')} at {f.get('stamp', float('nan')):.1f} s: {f.get('reason', '')}" for f in metrics.get("run", {}).get("failures", [])]


def run_table(result) -> Group:
    """Estimators and matchers of a finished run (fits 80 columns), then each expectation with its value."""
    m = result.metrics
    info = m["run"]
    title = (
        f"{info['scenario']}: {info['sim_s']:.0f} s simulated in {info['wall_s']:.0f} s "
        f"({_num(info['realtime_factor'], '.1f')}x real time), {info['scans']} scans, {info['fixes']} fixes"
    )
    table = Table(title=title, box=box.SIMPLE_HEAD, caption="m and deg; outage: in GPS blackouts; *: matcher odometry")
    table.add_column("under test", no_wrap=True)
    for col in ("APE\nrmse", "APE\np95", "APE\nmax", "outage\nmax", "RPE\n100 m", "yaw\np95", "match\nok", "Hz"):
        table.add_column(col, justify="right")
    for eid, e in m["estimators"].items():
        table.add_row(
            f"{eid} [bold red](failed)[/]" if e.get("failed") else eid,
            _num(e["ape"]["rmse"]),
            _num(e["ape"]["p95"]),
            _num(e["ape"]["max"]),
            _num(e["windows"]["blackout"]["max_error"]),
            _num(e["rpe_100m"]["mean"]),
            _num(e["yaw"]["p95"], ".1f"),
            "",
            "",
        )
    for mid, x in m["matchers"].items():
        table.add_row(
            f"{mid}* [bold red](failed)[/]" if x.get("failed") else f"{mid}*",
            _num(x["ape"]["rmse"]),
            _num(x["ape"]["p95"]),
            _num(x["ape"]["max"]),
            "",
            _num(x["rpe_100m"]["mean"]),
            _num(x["yaw"]["p95"], ".1f"),
            _num(x["success"], ".0%"),
            _num(x["hz"], ".0f"),
        )
    v = m.get("vessel", {})
    vessel = (
        f"vessel: {v.get('outcome')}, min clearance {_num(v.get('min_clearance_m'))} m ({v.get('min_clearance_part') or '-'}), "
        f"{_num(v.get('time_below_threshold_s'), '.1f')} s within {_num(v.get('clearance_threshold_m'), '.1f')} m, "
        f"cross-track max {_num(v.get('cross_track', {}).get('max'))} m"
    )
    expectations = Table(box=box.SIMPLE_HEAD, show_edge=False)
    for col, justify in (("", "left"), ("expectation", "left"), ("value", "right")):
        expectations.add_column(col, justify=justify)
    for outcome in m["expectations"]:
        mark = "[green]pass[/]" if outcome["pass"] else "[bold red]FAIL[/]"
        expectations.add_row(mark, outcome["expect"], _num(outcome["value"], ".3g"))
    for goal in m.get("goals", []):
        mark = {True: "[green]goal met[/]", False: "[yellow]goal NOT met[/]", None: "goal n/a"}[goal["met"]]
        expectations.add_row(mark, goal["goal"], _num(goal["value"], ".3g"))
    return Group(table, vessel, expectations) if m["expectations"] or m.get("goals") else Group(table, vessel)


def suite_table(cases) -> Table:
    """One row per scenario: pass/fail, expectations passed, speed, the first failure (fits 80 columns)."""
    table = Table(title="riverbench suite", box=box.SIMPLE_HEAD)
    table.add_column("scenario", no_wrap=True)
    table.add_column("result")
    table.add_column("expect-\nations", justify="right")
    table.add_column("x real\ntime", justify="right")
    table.add_column("wall\ns", justify="right")
    table.add_column("first failure", overflow="fold")
    for c in cases:
        passed = sum(e["pass"] for e in c.expectations)
        first = c.error or next((e["reason"] for e in c.expectations if not e["pass"]), "")
        table.add_row(
            c.label,
            "[green]pass[/]" if c.passed else "[bold red]FAIL[/]",
            f"{passed}/{len(c.expectations)}",
            _num(c.realtime_factor, ".1f"),
            f"{c.wall_s:.0f}",
            first,
        )
    return table


CHANGED_ROWS = 12
"""Metrics without a direction that moved, listed in the terminal before '... and N more' (all are in suite.json)."""


def regression_table(comparison) -> Table:
    """Regressions, then improvements, then moved metrics without a direction, grouped by scenario: metric, baseline
    median [min..max] over seeds, now, median paired change, verdict (fits 80 columns)."""
    table = Table(title="against the baseline", box=box.SIMPLE_HEAD, caption=comparison.sentence())
    table.add_column("metric", overflow="fold", min_width=28)
    for column in ("baseline median\n[min..max]", "now\nmedian", "change"):
        table.add_column(column, justify="right")
    table.add_column("verdict")
    style = {"regressed": "[bold red]regressed[/]", "improved": "[green]improved[/]", "changed": "changed"}
    changed = comparison.by("changed")
    shown = [*comparison.by("regressed"), *comparison.by("improved"), *changed[:CHANGED_ROWS]]
    scenario = None
    for v in sorted(shown, key=lambda v: v.scenario):  # stable: regressions first within a scenario
        if v.scenario != scenario:
            scenario = v.scenario
            table.add_row(f"[bold]{scenario}[/]", "", "", "", "")
        row = v.as_dict()
        base = f"{_num(row['baseline_median'], '.4g')}\n[{_num(row['baseline_min'], '.3g')}..{_num(row['baseline_max'], '.3g')}]"
        verdict = style[v.verdict] + ("" if v.gating else "\n(wall clock)")
        table.add_row(f"  {v.metric}", base, _num(row["now_median"], ".4g"), _change(row), verdict)
    if len(changed) > CHANGED_ROWS:
        table.add_row(f"... and {len(changed) - CHANGED_ROWS} more changed (suite.json)", "", "", "", "")
    return table


def _change(row: dict) -> str:
    """'+0.69 (+28%)': the median paired change, and relative to the baseline's median."""
    change, base = row["change"], row["baseline_median"]
    if change is None:
        return "–"
    relative = f" ({change / abs(base):+.0%})" if base else ""
    return f"{change:+.3g}\n{relative.strip()}" if relative else f"{change:+.3g}"
