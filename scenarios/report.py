"""The run report: plots/*.png, report.md and a self-contained report.html, from a run directory.

`write(run_dir)` reads only the run directory's files (metrics.json, scenario.toml, the TUM and CSV
files), so it serves at the end of a run and on any finished run directory later. The report is
built once as a list of blocks (headings, paragraphs, tables, figures) and rendered twice: as
Markdown referencing plots/*.png, and as HTML with the figures embedded as data: URIs.
Every file is written under a temporary name and renamed.
"""

from __future__ import annotations

import base64
import html
import json
import tomllib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from scenarios import plots, vessel_plot
from scenarios.atomic import atomic_path

NULL = "–"
CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; color: #222; max-width: 1150px;
       margin: 1.5em auto; padding: 0 1em; line-height: 1.45; }
h1 { margin-bottom: .2em; } h2 { margin-top: 1.8em; border-bottom: 1px solid #ddd; padding-bottom: .2em; }
p.meta { color: #555; margin: .2em 0; }
.scroll { overflow-x: auto; }
table { border-collapse: collapse; font-size: 13px; margin: .6em 0; }
th, td { border: 1px solid #c8c8c8; padding: 3px 8px; text-align: right; white-space: nowrap; }
th { background: #f1f3f5; }
th:first-child, td:first-child, th.text, td.text { text-align: left; white-space: normal; }
td.pass, p.pass { color: #176b2c; background: #e6f4ea; font-weight: 600; }
td.fail, p.fail { color: #b3261e; background: #fce8e6; font-weight: 600; }
p.pass, p.fail { display: inline-block; padding: 4px 10px; border-radius: 4px; }
p.note { font-size: 12px; color: #666; margin-top: 0; }
figure { margin: 1em 0; } figure img { width: 100%; border: 1px solid #eee; }
figcaption { font-size: 13px; color: #555; }
"""


@dataclass(frozen=True)
class Cell:
    """A table cell: its text, bold when best in its column, css 'pass'/'fail'/'text' or ''."""

    text: str
    bold: bool = False
    css: str = ""


@dataclass(frozen=True)
class Table:
    """A table: header, rows of cells, a note printed below it."""

    header: list[str]
    rows: list[list[Cell]]
    note: str = ""


@dataclass(frozen=True)
class Heading:
    """A section heading (level 1 is the title)."""

    level: int
    text: str


@dataclass(frozen=True)
class Text:
    """A paragraph; css 'meta', 'note', 'pass' or 'fail' styles it."""

    text: str
    css: str = ""


@dataclass(frozen=True)
class Image:
    """A figure: its path relative to the run directory, and its caption."""

    path: str
    caption: str


@dataclass(frozen=True)
class Column:
    """A metric column: title, how to get the value from a metrics node, how to print it, which way is better."""

    title: str
    value: Callable[[dict], float | None]
    fmt: Callable[[float | None], str]
    better: str | None = "low"  # "low", "high", or None (not ranked)
    text: bool = False  # words, not numbers: left-aligned
    detail: Callable[[dict], str] | None = None  # printed after the value (e.g. its spread over seeds), not ranked


@dataclass(frozen=True)
class Context:
    """What the report sections draw on."""

    metrics: dict
    info: dict
    images: dict[str, str]
    t0: float
    windows: dict


def write(run_dir: Path, scenario=None) -> None:
    """Write plots/*.png, report.md and report.html into a finished run directory."""
    run_dir = Path(run_dir)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    info = scenario_info(run_dir, scenario)
    series = plots.load(run_dir, list(metrics.get("estimators", {})), list(metrics.get("matchers", {})), hdop_limits(info))
    images = plots.write_all(series, run_dir / "plots")
    vessel_node = metrics.get("vessel", {})
    images |= vessel_plot.write(run_dir, float(vessel_node.get("clearance_threshold_m") or 0.0), vessel_node)
    ctx = Context(metrics, info, images, series.t0, plots.read_csv(run_dir / "windows.csv"))
    blocks = build(ctx)
    for name, text in (("report.md", to_markdown(blocks)), ("report.html", to_html(blocks, run_dir, title=f"riverbench: {name_of(ctx)}"))):
        with atomic_path(run_dir / name) as tmp:
            tmp.write_text(text, encoding="utf-8")
            tmp.chmod(plots.FILE_MODE)


def scenario_info(run_dir: Path, scenario) -> dict:
    """The resolved scenario as a dict (with its hash when known): from the model, else scenario.toml, else empty."""
    if scenario is not None:
        return {**scenario.resolved(), "hash": scenario.hash}
    path = run_dir / "scenario.toml"
    return tomllib.loads(path.read_text()) if path.exists() else {}


def hdop_limits(info: dict) -> dict[str, float]:
    """The HDOP threshold of each estimator whose monitor is 'hdop' and sets one."""
    return {e["id"]: float(e["monitor_params"]["max_hdop"]) for e in info.get("estimators", [])
            if e.get("monitor") == "hdop" and "max_hdop" in e.get("monitor_params", {})}


def name_of(ctx: Context) -> str:
    """The scenario's name (from the scenario, else from metrics.json)."""
    return ctx.info.get("name") or ctx.metrics.get("run", {}).get("scenario", "run")


# ---- formatting -------------------------------------------------------------------------------------

def num(value, fmt: str = ".2f", unit: str = "") -> str:
    """A number in `fmt` with an optional unit; null and NaN as '–'."""
    if value is None or value != value:
        return NULL
    return format(value, fmt) + unit


def metres(value) -> str:
    """A distance in metres (or degrees) with two decimals."""
    return num(value, ".2f")


def share(value) -> str:
    """A share (0..1) as a percentage."""
    return NULL if value is None or value != value else f"{100 * value:.1f} %"


def get(path: str) -> Callable[[dict], float | None]:
    """A getter of a dotted path in a metrics node (None when absent)."""
    def value(node: dict):
        """The value at the path, or None."""
        for key in path.split("."):
            node = node.get(key) if isinstance(node, dict) else None
        return node
    return value


# ---- blocks -----------------------------------------------------------------------------------------

def build(ctx: Context) -> list:
    """Every block of the report, in reading order."""
    return [*header(ctx), *failures(ctx), *expectations(ctx), *vessel(ctx), *figures(ctx, "vessel"), *estimators(ctx),
            *figures(ctx, "map", "error", "yaw"),
            *gps(ctx), *figures(ctx, "hdop_error"), *windows(ctx), *matchers(ctx), *figures(ctx, "matchers")]


def header(ctx: Context) -> list:
    """Title, description, identity of the run and how fast it ran."""
    run, info = ctx.metrics.get("run", {}), ctx.info
    blocks = [Heading(1, f"riverbench report: {name_of(ctx)}")]
    if info.get("description"):
        blocks.append(Text(info["description"]))
    identity = [f"seed {info.get('seed', run.get('seed', NULL))}", f"scenario hash {info.get('hash') or run.get('scenario_hash', NULL)}"]
    if info.get("world"):
        identity.append(f"world {info['world']}")
    identity.append(f"stretch {stretch_text(info.get('stretch', {}))}: t = {num(run.get('t_start'), '.1f')} … {num(run.get('t_end'), '.1f')} s")
    blocks.append(Text(" · ".join(identity), "meta"))
    blocks.append(Text(f"{num(run.get('sim_s'), '.0f')} s simulated in {num(run.get('wall_s'), '.1f')} s "
                       f"({num(run.get('realtime_factor'), '.1f')}× real time) · {run.get('scans', NULL)} scans · "
                       f"{run.get('fixes', NULL)} GPS fixes · peak memory {num(run.get('peak_rss_mb'), '.0f')} MB · "
                       f"{run.get('workers', NULL)} worker process{'' if run.get('workers') == 1 else 'es'}", "meta"))
    outcomes = ctx.metrics.get("expectations", [])
    passed = sum(bool(o.get("pass")) for o in outcomes)
    if outcomes:
        blocks.append(Text(f"Expectations: {passed} of {len(outcomes)} passed", "pass" if passed == len(outcomes) else "fail"))
    return blocks


def stretch_text(stretch: dict) -> str:
    """The stretch as the scenario gives it: by route station or by time."""
    if "start_m" in stretch or "end_m" in stretch:
        end = f"{stretch['end_m']:.0f} m" if "end_m" in stretch else "the route's end"
        return f"{stretch.get('start_m', 0.0):.0f} m to {end} along the route"
    if "start_s" in stretch or "end_s" in stretch:
        end = f"{stretch['end_s']:.1f} s" if "end_s" in stretch else "its end"
        return f"{stretch.get('start_s', 0.0):.1f} s to {end} of the trajectory"
    return "the whole route"


def failures(ctx: Context) -> list:
    """Components that failed during the run (none: no section)."""
    rows = [[Cell(f.get("component", NULL), css="fail"), Cell(str(f.get("id", NULL))), Cell(num(f.get("stamp"), ".2f")),
             Cell(str(f.get("reason", "")), css="text")] for f in ctx.metrics.get("run", {}).get("failures", [])]
    return [Heading(2, "Failures"), Table(["component", "id", "at t (s)", "reason"], rows)] if rows else []


def expectations(ctx: Context) -> list:
    """Each expectation with its value and PASS or FAIL (and why)."""
    outcomes = ctx.metrics.get("expectations", [])
    if not outcomes:
        return [Heading(2, "Expectations"), Text("The scenario sets no expectations.")]
    rows = [[Cell(o["expect"], css="text"), Cell(num(o.get("value"), ".4g")),
             Cell("PASS" if o.get("pass") else "FAIL", css="pass" if o.get("pass") else "fail"),
             Cell(o.get("reason") or "", css="text")] for o in outcomes]
    return [Heading(2, "Expectations"), Table(["expectation", "value", "result", "reason"], rows)]


def vessel(ctx: Context) -> list:
    """How the vessel fared: steered on what, how it ended, its closest approach to a structure and its cross-track error."""
    node = ctx.metrics.get("vessel")
    if not node:
        return []
    control = ctx.info.get("control", {})
    mode = control.get("mode", "open_loop")
    steering = ("open loop: the vessel follows the route exactly" if mode == "open_loop"
                else f"closed loop: the autopilot steers on {control.get('steer_on', '?')} (heading from the {control.get('heading', 'compass')})")
    ended = {"completed": "reached the end of the stretch", "collision": f"hit {node.get('collision_part')} at t = {num(node.get('collision_t'), '.1f')} s",
             "time_limit": "ran out of time before the end of the stretch", "interrupted": "stopped early"}.get(node.get("outcome"), str(node.get("outcome")))
    cross = node.get("cross_track", {})
    rows = [[Cell(str(node.get("outcome")), css="pass" if node.get("outcome") == "completed" else "fail"),
             Cell(f"{metres(node.get('min_clearance_m'))} ({node.get('min_clearance_part') or NULL})"),
             Cell(num(node.get("time_below_threshold_s"), ".1f")), Cell(metres(cross.get("mean"))), Cell(metres(cross.get("p95"))),
             Cell(metres(cross.get("max"))), Cell(num(node.get("distance_m"), ".0f"))]]
    note = (f"{steering}; it {ended}. Clearance: the distance from the hull to the nearest structure (overhead decks excluded); "
            f"time within {num(node.get('clearance_threshold_m'), '.1f')} m of one; cross-track: the true offset from the route, metres.")
    return [Heading(2, "Vessel"), Table(["outcome", "min clearance (nearest)", "s below threshold", "cross-track mean", "p95", "max",
                                         "distance (m)"], rows, note)]


ACCURACY_COLUMNS = [
    Column("available", get("available"), share, "high"),
    Column("APE rmse", get("ape.rmse"), metres),
    Column("APE median", get("ape.median"), metres),
    Column("APE p95", get("ape.p95"), metres),
    Column("APE max", get("ape.max"), metres),
    Column("RPE 10 m", get("rpe_10m.mean"), metres),
    Column("RPE 100 m", get("rpe_100m.mean"), metres),
    Column("yaw p95 (°)", get("yaw.p95"), metres),
]
DEGRADATION_COLUMNS = [
    Column("blackout max", get("windows.blackout.max_error"), metres),
    Column("blackout exit", get("windows.blackout.exit_error"), metres),
    Column("reacquisition max", get("windows.reacquisition.max_error"), metres),
    Column("NLOS max", get("windows.nlos.max_error"), metres),
    Column("injected max", get("windows.injected.max_error"), metres),
    Column("monitor", get("monitor_kind"), lambda v: NULL if v is None else str(v), None, text=True),
    Column("recall", get("monitor.added_5m.recall"), share, "high"),
    Column("false alarms", get("monitor.added_5m.false_alarm_rate"), share),
]


def estimators(ctx: Context) -> list:
    """Two tables, a row per estimator: accuracy over the run; worst errors through GPS degradation and monitor scores."""
    nodes = ctx.metrics.get("estimators", {})
    if not nodes:
        return []
    monitors = {e["id"]: e.get("monitor", "none") for e in ctx.info.get("estimators", []) if "id" in e}
    labels = {eid: _failed_label(eid, n) for eid, n in nodes.items()}
    accuracy = ranked_table("estimator", nodes, ACCURACY_COLUMNS, labels,
                            note="Horizontal errors in metres over the scans with an estimate (available); RPE: mean error per 10 m "
                                 "and per 100 m of true travel. Bold: best in its column.")
    # no monitor: its scores mean nothing; a window kind the run never met: its column would be all '–'
    nodes = {eid: {**(n if monitors.get(eid, "none") != "none" else _without_monitor(n)), "monitor_kind": monitors.get(eid)}
             for eid, n in nodes.items()}
    columns = [c for c in DEGRADATION_COLUMNS if any(c.value(n) is not None for n in nodes.values())]
    degradation = ranked_table("estimator", nodes, columns, labels,
                               note="Worst horizontal error (m) inside any window of that kind, and at a blackout's end (exit). "
                                    "Monitor: recall and false-alarm rate on measured fixes whose environment-added error exceeds 5 m. "
                                    "Bold: best in its column.")
    return [Heading(2, "Estimators"), accuracy, Heading(3, "Through GPS degradation"), degradation]


def _without_monitor(node: dict) -> dict:
    """The metrics node with its monitor scores removed (an estimator without a monitor)."""
    return {k: v for k, v in node.items() if k != "monitor"}


def _failed_label(eid: str, node: dict) -> str:
    """The row label of an estimator or matcher: its id, and when it failed."""
    return f"{eid} (failed at {num(node.get('failed_at'), '.1f')} s)" if node.get("failed") else eid


MATCHER_COLUMNS = [
    Column("success", get("success"), share, "high"),
    Column("gated", get("gated"), share),
    Column("Hz", get("hz"), lambda v: num(v, ".1f"), "high"),
    Column("ms p95", get("ms.p95"), lambda v: num(v, ".1f")),
    Column("points median", get("points.median"), lambda v: num(v, ".0f"), None),
    Column("degenerate", get("degenerate"), share),
    Column("APE aligned rmse", get("ape_aligned.rmse"), metres),
    Column("RPE 10 m", get("rpe_10m.mean"), metres),
    Column("RPE 100 m", get("rpe_100m.mean"), metres),
    Column("yaw p95 (°)", get("yaw.p95"), metres),
]


def matchers(ctx: Context) -> list:
    """One row per scan matcher: success, speed, points, degeneracy and odometry accuracy."""
    nodes = ctx.metrics.get("matchers", {})
    if not nodes:
        return []
    note = ("Success: share of scans after the first with a usable match; gated: dropped by the point-count gate; "
            "degenerate: usable matches with an unobserved direction. Errors (m) of the odometry chained from the true "
            "start pose; APE aligned: after the best-fit rigid planar motion. Bold: best in its column.")
    return [Heading(2, "Scan matchers"), ranked_table("matcher", nodes, MATCHER_COLUMNS, {mid: _failed_label(mid, n) for mid, n in nodes.items()}, note)]


def ranked_table(first: str, nodes: dict[str, dict], columns: list[Column], labels: dict[str, str], note: str = "") -> Table:
    """A row per node, a cell per column; the best value of each ranked column in bold (none when all equal)."""
    texts = {c.title: {k: c.fmt(c.value(n)) for k, n in nodes.items()} for c in columns}
    best = {c.title: _best_text(c, nodes) for c in columns}
    rows = [[Cell(labels[k], css="fail" if n.get("failed") else "")]
            + [Cell(texts[c.title][k] + (c.detail(n) if c.detail else ""), bold=texts[c.title][k] == best[c.title], css="text" if c.text else "")
               for c in columns]
            for k, n in nodes.items()]
    return Table([first, *(c.title for c in columns)], rows, note)


def _best_text(column: Column, nodes: dict[str, dict]) -> str | None:
    """The printed best value of a ranked column, or None when unranked or when no value stands out."""
    values = [v for v in (column.value(n) for n in nodes.values()) if v is not None and v == v]
    if column.better is None or len({column.fmt(v) for v in values}) < 2:
        return None
    return column.fmt(min(values) if column.better == "low" else max(values))


def gps(ctx: Context) -> list:
    """The receiver: availability, shares, HDOP, and its true error split into open-sky and environment-added."""
    g = ctx.metrics.get("gps")
    if not g:
        return []
    shares = Table(["fixes", "measured", "valid (incl. dead reckoning)", "blackout", "NLOS share", "HDOP median", "faulty (> 5 m)"],
                   [[Cell(str(g.get("fixes", NULL))), Cell(share(g.get("availability"))), Cell(share(g.get("valid"))),
                     Cell(share(g.get("blackout"))), Cell(share(g.get("nlos_share"))), Cell(num(g.get("hdop_median"), ".2f")),
                     Cell(share(g.get("faulty_5m")))]])
    keys = ("rmse", "mean", "median", "p95", "max")
    errors = Table(["horizontal error of measured fixes (m)", *keys],
                   [[Cell(label)] + [Cell(metres((g.get(node) or {}).get(k))) for k in keys]
                    for node, label in (("error", "true error"), ("open_sky_error", "open-sky part"), ("added_error", "added by the environment"))])
    return [Heading(2, "GPS"), shares, errors]


WINDOW_KEYS = ("max_error", "exit_error", "recover_s")


def windows(ctx: Context) -> list:
    """Every GPS-degradation window with each estimator's worst and exit error and its recovery time."""
    w = ctx.windows
    kinds = w.get("kind", [])
    if not len(kinds):
        return [Heading(2, "GPS-degradation windows"), Text("No blackout, NLOS, re-acquisition or injected-fault window in this run.")]
    eids = [e for e in ctx.metrics.get("estimators", {}) if f"{e}.max_error" in w]
    rows = []
    for i, kind in enumerate(kinds):
        cells = [Cell(str(kind)), Cell(num(w["start"][i] - ctx.t0, ".1f")), Cell(num(w["end"][i] - ctx.t0, ".1f")), Cell(num(w["duration"][i], ".1f"))]
        cells += [Cell(passage_text(w[f"{e}.max_error"][i], w[f"{e}.exit_error"][i], w[f"{e}.recover_s"][i])) for e in eids]
        rows.append(cells)
    note = ("Times in seconds since the first scan. Per estimator: the worst horizontal error in the window / at its end, "
            "in metres, and (in brackets) how long after the window it took to come back within 1 m of its error at entry "
            "(never: not by the end of the run).")
    return [Heading(2, "GPS-degradation windows"), Table(["kind", "start (s)", "end (s)", "duration (s)", *eids], rows, note)]


def passage_text(max_error: float, exit_error: float, recover_s: float) -> str:
    """'max / exit (recovery)' of one estimator through one window."""
    if max_error != max_error:
        return NULL
    recovery = "never" if recover_s != recover_s else f"{recover_s:.1f} s"
    return f"{metres(max_error)} / {metres(exit_error)} ({recovery})"


def figures(ctx: Context, *stems: str) -> list:
    """The figures among `stems` that were drawn."""
    return [Image(f"plots/{s}.png", ctx.images[f"plots/{s}.png"]) for s in stems if f"plots/{s}.png" in ctx.images]


# ---- rendering --------------------------------------------------------------------------------------

def to_markdown(blocks: list) -> str:
    """The blocks as GitHub-flavoured Markdown (figures by relative path)."""
    out = []
    for b in blocks:
        if isinstance(b, Heading):
            out.append(f"{'#' * b.level} {b.text}")
        elif isinstance(b, Text):
            out.append(f"**{b.text}**" if b.css in ("pass", "fail") else b.text)
        elif isinstance(b, Table):
            out.append(_markdown_table(b))
        elif isinstance(b, Image):
            out.append(f"![{b.caption}]({b.path})\n\n*{b.caption}*")
    return "\n\n".join(out) + "\n"


def _markdown_table(table: Table) -> str:
    """A Markdown table (first column left-aligned, the rest right-aligned) and its note."""
    def cell(c: Cell) -> str:
        """One Markdown cell: pipes escaped, bold when best or failed."""
        text = c.text.replace("|", "\\|")
        return f"**{text}**" if text and (c.bold or c.css == "fail") else text
    lines = ["| " + " | ".join(h.replace("|", "\\|") for h in table.header) + " |",
             "|" + "|".join([":---"] + ["---:"] * (len(table.header) - 1)) + "|"]
    lines += ["| " + " | ".join(cell(c) for c in row) + " |" for row in table.rows]
    return "\n".join(lines) + (f"\n\n*{table.note}*" if table.note else "")


def to_html(blocks: list, run_dir: Path, title: str) -> str:
    """The blocks as one self-contained HTML page: inline CSS, figures as base64 data: URIs."""
    body = []
    for b in blocks:
        if isinstance(b, Heading):
            body.append(f"<h{b.level}>{html.escape(b.text)}</h{b.level}>")
        elif isinstance(b, Text):
            body.append(f'<p class="{b.css}">{html.escape(b.text)}</p>' if b.css else f"<p>{html.escape(b.text)}</p>")
        elif isinstance(b, Table):
            body.append(_html_table(b))
        elif isinstance(b, Image):
            data = base64.b64encode((run_dir / b.path).read_bytes()).decode("ascii")
            body.append(f'<figure><img src="data:image/png;base64,{data}" alt="{html.escape(b.caption)}">'
                        f"<figcaption>{html.escape(b.caption)}</figcaption></figure>")
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n<title>{html.escape(title)}</title>\n'
            f"<style>{CSS}</style>\n</head>\n<body>\n" + "\n".join(body) + "\n</body>\n</html>\n")


def _html_table(table: Table) -> str:
    """An HTML table in a horizontally scrolling box, and its note."""
    def cell(c: Cell) -> str:
        """One <td>: escaped, bold when best, classed pass/fail/text."""
        text = html.escape(c.text)
        text = f"<b>{text}</b>" if c.bold else text
        return f'<td class="{c.css}">{text}</td>' if c.css else f"<td>{text}</td>"
    text_columns = {i for row in table.rows for i, c in enumerate(row) if c.css == "text"}
    head = "".join(f'<th class="text">{html.escape(h)}</th>' if i in text_columns else f"<th>{html.escape(h)}</th>"
                   for i, h in enumerate(table.header))
    rows = "".join("<tr>" + "".join(cell(c) for c in row) + "</tr>\n" for row in table.rows)
    note = f'<p class="note">{html.escape(table.note)}</p>' if table.note else ""
    return f'<div class="scroll"><table>\n<tr>{head}</tr>\n{rows}</table></div>{note}'
