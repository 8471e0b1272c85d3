"""One-screen summary tables of a run and of a suite (rich)."""

from __future__ import annotations

from rich.table import Table


def _num(value, fmt: str = ".2f") -> str:
    return "–" if value is None else format(value, fmt)


def run_table(result) -> Table:
    """Estimators, matchers and expectations of a finished run."""
    m = result.metrics
    info = m["run"]
    table = Table(title=f"{info['scenario']}: {info['sim_s']:.0f} s simulated in {info['wall_s']:.0f} s "
                        f"({_num(info['realtime_factor'], '.1f')}x real time), {info['scans']} scans, {info['fixes']} fixes")
    for col in ("under test", "APE rmse", "p95", "max", "blackout max", "RPE 100 m", "yaw p95", "success", "Hz"):
        table.add_column(col, justify="right" if col != "under test" else "left")
    for eid, e in m["estimators"].items():
        table.add_row(eid, _num(e["ape"]["rmse"]), _num(e["ape"]["p95"]), _num(e["ape"]["max"]),
                      _num(e["windows"]["blackout"]["max_error"]), _num(e["rpe_100m"]["mean"]), _num(e["yaw"]["p95"], ".1f"), "", "")
    for mid, x in m["matchers"].items():
        table.add_row(f"{mid} (odometry)", _num(x["ape"]["rmse"]), _num(x["ape"]["p95"]), _num(x["ape"]["max"]), "",
                      _num(x["rpe_100m"]["mean"]), _num(x["yaw"]["p95"], ".1f"), _num(x["success"], ".1%"), _num(x["hz"], ".0f"))
    for outcome in m["expectations"]:
        mark = "[green]pass[/]" if outcome["pass"] else "[bold red]FAIL[/]"
        table.add_row(f"{mark} {outcome['expect']}", _num(outcome["value"], ".3g"), *[""] * 7)
    return table


def suite_table(cases) -> Table:
    """One row per scenario: pass/fail, expectations passed, speed, the first failure."""
    table = Table(title="riverbench suite")
    for col in ("scenario", "result", "expectations", "x real time", "wall s", "first failure"):
        table.add_column(col)
    for c in cases:
        passed = sum(e["pass"] for e in c.expectations)
        first = c.error or next((e["reason"] for e in c.expectations if not e["pass"]), "")
        table.add_row(c.name, "[green]pass[/]" if c.passed else "[bold red]FAIL[/]", f"{passed}/{len(c.expectations)}",
                      _num(c.realtime_factor, ".1f"), f"{c.wall_s:.0f}", first)
    return table
