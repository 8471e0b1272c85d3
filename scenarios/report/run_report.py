"""The run report: plots/*.png, report.md and a self-contained report.html, from a run directory.

`write(run_dir)` reads only the run directory's files (metrics.json, scenario.toml, the TUM and CSV
files), so it serves at the end of a run and on any finished run directory later. The report is
built once as a list of blocks (headings, paragraphs, tables, figures) and rendered twice: as
Markdown referencing plots/*.png, and as HTML with the figures embedded as data: URIs.
Every file is written under a temporary name and renamed.
"""

from __future__ import annotations

import json
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

from riverbench.atomic import atomic_path
from scenarios.report import plots, vessel_plot, world_map
from scenarios.report.document import NULL, Cell, Column, Heading, Image, Table, Text, get, metres, num, ranked_table, share, to_html, to_markdown
from scenarios.report.refusals import refusals
from scenarios.score import units


@dataclass(frozen=True)
class Context:
    """What the report sections draw on."""

    metrics: dict
    info: dict
    images: dict[str, str]
    t0: float
    windows: dict
    fixes: dict = field(default_factory=dict)
    """gps.csv's columns (empty: no fixes to count refusals in)."""


def write(run_dir: Path, scenario=None) -> None:
    """Write plots/*.png, report.md and report.html into a finished run directory."""
    run_dir = Path(run_dir)
    metrics = json.loads((run_dir / "metrics.json").read_text())
    info = scenario_info(run_dir, scenario)
    alert_limit = float((info.get("integrity") or {}).get("alert_limit_m", plots.RunSeries.alert_limit_m))
    series = plots.load(
        run_dir, list(metrics.get("estimators", {})), list(metrics.get("matchers", {})), hdop_limits(info), world_map.load(info), alert_limit
    )
    images = plots.write_all(series, run_dir / "plots")
    vessel_node = metrics.get("vessel", {})
    images |= vessel_plot.write(run_dir, float(vessel_node.get("clearance_threshold_m") or 0.0), vessel_node)
    ctx = Context(metrics, info, images, series.t0, plots.read_csv(run_dir / "windows.csv"), series.gps)
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
    return {
        e["id"]: float(e["monitor_params"]["max_hdop"])
        for e in info.get("estimators", [])
        if e.get("monitor") == "hdop" and "max_hdop" in e.get("monitor_params", {})
    }


def name_of(ctx: Context) -> str:
    """The scenario's name (from the scenario, else from metrics.json)."""
    return ctx.info.get("name") or ctx.metrics.get("run", {}).get("scenario", "run")


# ---- formatting -------------------------------------------------------------------------------------


# ---- blocks -----------------------------------------------------------------------------------------


def build(ctx: Context) -> list:
    """Every block of the report, in reading order."""
    return [
        *header(ctx),
        *failures(ctx),
        *expectations(ctx),
        *goals(ctx),
        *vessel(ctx),
        *figures(ctx, "vessel"),
        *estimators(ctx),
        *figures(ctx, "map", "error", "yaw", "stanford"),
        *gps(ctx),
        *figures(ctx, "hdop_error"),
        *windows(ctx),
        *matchers(ctx),
        *figures(ctx, "matchers"),
        *scored_in(ctx),
        *commands(ctx),
    ]


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
    blocks.append(
        Text(
            f"{num(run.get('sim_s'), '.0f')} s simulated in {num(run.get('wall_s'), '.1f')} s "
            f"({num(run.get('realtime_factor'), '.1f')}× real time) · {run.get('scans', NULL)} scans · "
            f"{run.get('fixes', NULL)} GPS fixes · peak memory {num(run.get('peak_rss_mb'), '.0f')} MB · "
            f"{run.get('workers', NULL)} worker process{'' if run.get('workers') == 1 else 'es'}",
            "meta",
        )
    )
    outcomes = ctx.metrics.get("expectations", [])
    passed = sum(bool(o.get("pass")) for o in outcomes)
    if outcomes:
        blocks.append(Text(f"Expectations: {passed} of {len(outcomes)} passed", "pass" if passed == len(outcomes) else "fail"))
    promised = ctx.metrics.get("goals", [])
    met = sum(g.get("met") is True for g in promised)
    judged = sum(g.get("met") is not None for g in promised)
    if judged:
        blocks.append(Text(f"Goals: {met} of {judged} met", "pass" if met == judged else "fail"))
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
    rows = [
        [
            Cell(f.get("component", NULL), css="fail"),
            Cell(str(f.get("id", NULL))),
            Cell(num(f.get("stamp"), ".2f")),
            Cell(str(f.get("reason", "")), css="text"),
        ]
        for f in ctx.metrics.get("run", {}).get("failures", [])
    ]
    note = "t: scenario time, seconds since the trajectory's start."
    return [Heading(2, "Failures"), Table(["component", "id", "at t (s)", "reason"], rows, note)] if rows else []


def expectations(ctx: Context) -> list:
    """Each expectation with its value and PASS or FAIL (and why)."""
    outcomes = ctx.metrics.get("expectations", [])
    if not outcomes:
        return [Heading(2, "Expectations"), Text("The scenario sets no expectations.")]
    rows = [
        [
            Cell(o["expect"], css="text"),
            Cell(num(o.get("value"), ".4g")),
            Cell(unit_of(o["expect"].split()[0]), css="text"),
            Cell("PASS" if o.get("pass") else "FAIL", css="pass" if o.get("pass") else "fail"),
            Cell(o.get("reason") or "", css="text"),
        ]
        for o in outcomes
    ]
    note = "Value: the metric at that dotted path of metrics.json, in the unit its `units` block gives."
    return [Heading(2, "Expectations"), Table(["expectation", "value", "unit", "result", "reason"], rows, note)]


def goals(ctx: Context) -> list:
    """Each goal (the product's promise) with its value and met or not: a missed goal is shown, never hidden."""
    records = ctx.metrics.get("goals", [])
    if not records:
        return []
    rows = [
        [
            Cell(g["goal"], css="text"),
            Cell(num(g.get("value"), ".4g")),
            Cell(unit_of(g["goal"].split()[0]), css="text"),
            Cell(*{True: ("met", False, "pass"), False: ("NOT MET", False, "fail"), None: ("n/a", False, "text")}[g.get("met")]),
            Cell(g.get("reason") or "", css="text"),
        ]
        for g in records
    ]
    note = (
        "Goals are the scenario's promises (an issue's targets), kept apart from the expectations a baseline's spread "
        "derives: a goal not met is a shortfall of the algorithms, reported here and in docs/results.md, and does not fail the run."
    )
    return [Heading(2, "Goals"), Table(["goal", "value", "unit", "result", "reason"], rows, note)]


def unit_of(path: str) -> str:
    """The unit of a metric's dotted path (scenarios.score.units), '–' when it has none."""
    quantity = units.quantity_of(path)
    return NULL if quantity is None else quantity.unit


def vessel(ctx: Context) -> list:
    """How the vessel fared: steered on what, how it ended, its closest approach to a structure and its cross-track error."""
    node = ctx.metrics.get("vessel")
    if not node:
        return []
    control = ctx.info.get("control", {})
    mode = control.get("mode", "open_loop")
    steering = (
        "open loop: the vessel follows the route exactly"
        if mode == "open_loop"
        else f"closed loop: the autopilot steers on {control.get('steer_on', '?')} (heading from the {control.get('heading', 'compass')})"
    )
    ended = {
        "completed": "reached the end of the stretch",
        "collision": f"hit {node.get('collision_part')} at t = {num(node.get('collision_t'), '.1f')} s",
        "time_limit": "ran out of time before the end of the stretch",
        "interrupted": "stopped early",
    }.get(node.get("outcome"), str(node.get("outcome")))
    cross = node.get("cross_track", {})
    rows = [
        [
            Cell(str(node.get("outcome")), css="pass" if node.get("outcome") == "completed" else "fail"),
            Cell(f"{metres(node.get('min_clearance_m'))} ({node.get('min_clearance_part') or NULL})"),
            Cell(num(node.get("time_below_threshold_s"), ".1f")),
            Cell(metres(cross.get("mean"))),
            Cell(metres(cross.get("p95"))),
            Cell(metres(cross.get("max"))),
            Cell(num(node.get("distance_m"), ".0f")),
        ]
    ]
    note = (
        f"{steering}; it {ended}. Clearance: the distance from the hull to the nearest structure (overhead decks excluded); "
        f"time within {num(node.get('clearance_threshold_m'), '.1f')} m of one; cross-track: the true offset from the route."
    )
    return [
        Heading(2, "Vessel"),
        Table(
            ["outcome", "min clearance (m) (nearest part)", "time below threshold (s)", "cross-track mean (m)", "p95 (m)", "max (m)", "distance (m)"],
            rows,
            note,
        ),
    ]


def degrees(value) -> str:
    """An angle in degrees with two decimals."""
    return num(value, ".2f")


def _recall_defined(node: dict) -> bool:
    """Whether the monitor caught any faulty fix: a false-alarm rate beside no recall (no faulty fix, or none flagged)
    is no merit, so it is shown but never ranked best."""
    recall = get("monitor.added_5m.recall")(node)
    return recall is not None and recall == recall and recall > 0


ACCURACY_COLUMNS = [
    Column("available", get("available"), share, "high"),
    Column("APE rmse (m)", get("ape.rmse"), metres),
    Column("APE median (m)", get("ape.median"), metres),
    Column("APE p95 (m)", get("ape.p95"), metres),
    Column("APE max (m)", get("ape.max"), metres),
    Column("RPE 10 m (m)", get("rpe_10m.mean"), metres),
    Column("RPE 100 m (m)", get("rpe_100m.mean"), metres),
    Column("yaw p95 (°)", get("yaw.p95"), degrees),
]
WINDOW_COLUMNS = [
    Column("blackout max (m)", get("windows.blackout.max_error"), metres),
    Column("blackout exit (m)", get("windows.blackout.exit_error"), metres),
    Column("reacquisition max (m)", get("windows.reacquisition.max_error"), metres),
    Column("NLOS max (m)", get("windows.nlos.max_error"), metres),
    Column("injected max (m)", get("windows.injected.max_error"), metres),
    Column("blackout yaw p95 (°)", get("windows.blackout.yaw.p95"), degrees),
    Column("NLOS yaw p95 (°)", get("windows.nlos.yaw.p95"), degrees),
]
MONITOR_COLUMNS = [
    Column("monitor", get("monitor_kind"), lambda v: NULL if v is None else str(v), None, text=True),
    Column("faulty fixes", get("monitor.added_5m.faulty"), lambda v: num(v, ".0f"), None),
    Column("recall", get("monitor.added_5m.recall"), share, "high"),
    Column("false alarms", get("monitor.added_5m.false_alarm_rate"), share, ranked_if=_recall_defined),
]
INTEGRITY_COLUMNS = [
    Column("HPL median (m)", get("integrity.hpl.median"), metres, None),
    Column("HPL p95 (m)", get("integrity.hpl.p95"), metres, None),
    Column("misleading", get("integrity.misleading"), share),
    Column("misleading epochs", get("integrity.misleading_epochs"), lambda v: num(v, ".0f")),
    Column("hazardous epochs", get("integrity.hazardous_epochs"), lambda v: num(v, ".0f")),
    Column("available (HPL < AL)", get("integrity.available"), share, "high"),
]
DEGRADATION_COLUMNS = [*WINDOW_COLUMNS, *MONITOR_COLUMNS]
WINDOW_NOTE = (
    "Worst horizontal error (m) inside any window of that kind, and at a blackout's end (exit); yaw: the heading "
    "error's p95 (deg) over the scans inside the windows of that kind."
)
MONITOR_NOTE = (
    "Monitor: its verdicts on the measured fixes; faulty fixes: how many had more than 5 m added by the environment; "
    "recall: the share of those it flagged (– when there were none); false alarms: the share of the other measured "
    "fixes it flagged, ranked only beside a recall above 0 (flagging nothing is no merit)."
)


def estimators(ctx: Context) -> list:
    """Two tables, a row per estimator: accuracy over the run; worst errors through GPS degradation and monitor scores."""
    nodes = ctx.metrics.get("estimators", {})
    if not nodes:
        return []
    monitors = {e["id"]: e.get("monitor", "none") for e in ctx.info.get("estimators", []) if "id" in e}
    labels = {eid: _failed_label(eid, n) for eid, n in nodes.items()}
    accuracy = ranked_table(
        "estimator",
        nodes,
        ACCURACY_COLUMNS,
        labels,
        note="Available: share of the run's scans with an estimate (an estimator that starts late or stops has less); "
        "errors: horizontal, in metres, over those scans; RPE: mean error per 10 m and per 100 m of true travel; "
        "yaw: heading error in degrees. Bold: best in its column.",
    )
    # no monitor: its scores mean nothing; a window kind the run never met: its column would be all '–'
    nodes = {
        eid: {**(n if monitors.get(eid, "none") != "none" else _without_monitor(n)), "monitor_kind": monitors.get(eid)} for eid, n in nodes.items()
    }
    columns = [c for c in WINDOW_COLUMNS if any(c.value(n) is not None for n in nodes.values())]
    notes = [WINDOW_NOTE] if columns else []
    if any(monitors.get(eid, "none") != "none" for eid in nodes):
        columns += MONITOR_COLUMNS
        notes.append(MONITOR_NOTE)
    blocks = [Heading(2, "Estimators"), accuracy]
    if columns:
        note = " ".join([*notes, "Bold: best in its column."])
        blocks += [Heading(3, "Through GPS degradation"), ranked_table("estimator", nodes, columns, labels, note)]
    return blocks + refusals(ctx.fixes, list(nodes)) + integrity(ctx)


def integrity(ctx: Context) -> list:
    """The protection levels' standard figures, a row per estimator that reports one (none: no block)."""
    nodes = {eid: n for eid, n in ctx.metrics.get("estimators", {}).items() if (n.get("integrity") or {}).get("misleading") is not None}
    if not nodes:
        return []
    alert = next(iter(nodes.values()))["integrity"].get("alert_limit_m")
    note = (
        f"Each estimator's horizontal protection level (HPL) at its integrity risk (fusion.integrity), per scan: misleading, "
        f"the share of scans whose error exceeded it; hazardous, those whose error exceeded the alert limit ({num(alert, 'g')} m) "
        f"while HPL was below it; available, the share of the run's scans with HPL below the alert limit. Bold: best in its column."
    )
    labels = {eid: _failed_label(eid, n) for eid, n in nodes.items()}
    return [Heading(3, "Integrity"), ranked_table("estimator", nodes, INTEGRITY_COLUMNS, labels, note)]


def _without_monitor(node: dict) -> dict:
    """The metrics node with its monitor scores removed (an estimator without a monitor)."""
    return {k: v for k, v in node.items() if k != "monitor"}


def _failed_label(eid: str, node: dict) -> str:
    """The row label of an estimator or matcher: its id, and when it failed (a command component fails as a whole)."""
    if not node.get("failed"):
        return eid
    return f"{eid} (failed at {num(node.get('failed_at'), '.1f')} s)" if node.get("failed_at") is not None else f"{eid} (failed)"


MATCHER_COLUMNS = [
    Column("success", get("success"), share, "high"),
    Column("gated", get("gated"), share),
    Column("Hz", get("hz"), lambda v: num(v, ".1f"), "high"),
    Column("time p95 (ms)", get("ms.p95"), lambda v: num(v, ".1f")),
    Column("points (median)", get("points.median"), lambda v: num(v, ".0f"), None),
    Column("degenerate", get("degenerate"), share),
    Column("APE aligned rmse (m)", get("ape_aligned.rmse"), metres),
    Column("RPE 10 m (m)", get("rpe_10m.mean"), metres),
    Column("RPE 100 m (m)", get("rpe_100m.mean"), metres),
    Column("yaw p95 (°)", get("yaw.p95"), degrees),
]


def matchers(ctx: Context) -> list:
    """One row per scan matcher: success, speed, points, degeneracy and odometry accuracy."""
    nodes = ctx.metrics.get("matchers", {})
    if not nodes:
        return []
    note = (
        "Success: share of scans after the first with a usable match; gated: dropped by the point-count gate; "
        "Hz and time: wall-clock rate and 95th-percentile time per registered scan; points: per scan, median; "
        "degenerate: usable matches with an unobserved direction. Errors (m) of the odometry chained from the true "
        "start pose; APE aligned: after the best-fit rigid planar motion; yaw in degrees. Bold: best in its column."
    )
    return [
        Heading(2, "Scan matchers"),
        ranked_table("matcher", nodes, MATCHER_COLUMNS, {mid: _failed_label(mid, n) for mid, n in nodes.items()}, note),
    ]


ANCHOR_TEXT = {
    "map": "in the map frame as given",
    "first": "odometry laid onto the truth at its first pose",
    "se2": "aligned to the truth (best rigid planar motion)",
    "se3": "aligned to the truth (best rigid 3-D motion)",
}


def scored_in(ctx: Context) -> list:
    """The components scored in after the run from trajectories made outside the bench (`riverbench score`), with the file
    and the contract each was read under (none: no section)."""
    rows = []
    for section in ("estimators", "matchers"):
        for cid, node in ctx.metrics.get(section, {}).items():
            source = node.get("source")
            if not isinstance(source, dict):
                continue
            contract = f"{source.get('format')}, {source.get('frame')} poses, {source.get('clock')} clock"
            rows.append(
                [
                    Cell(cid),
                    Cell(section[:-1]),
                    Cell(str(source.get("file")), css="text"),
                    Cell(contract, css="text"),
                    Cell(ANCHOR_TEXT.get(str(source.get("anchor")), str(source.get("anchor"))), css="text"),
                    Cell(share(node.get("coverage"))),
                ]
            )
    if not rows:
        return []
    note = (
        "Trajectories made outside the bench, scored into this run by `riverbench score` with the metrics of the tables above. "
        "Coverage: the share of the run's scans that got a pose (each scan takes the pose stamped nearest it within a quarter "
        "of a revolution); a dropped frame counts as none. A matcher's errors are those of its trajectory anchored as stated."
    )
    return [Heading(2, "Scored in afterwards"), Table(["component", "scored as", "file", "contract", "anchor", "coverage"], rows, note)]


def commands(ctx: Context) -> list:
    """The command components (an executable run on the run's recording): how each ended and what it cost apart from the
    bench (none: no section)."""
    rows = []
    for section in ("estimators", "matchers"):
        for cid, node in ctx.metrics.get(section, {}).items():
            ext = node.get("external")
            if not isinstance(ext, dict):
                continue
            status = Cell(f"failed: {node.get('reason', '')}", css="fail") if node.get("failed") else Cell("ok", css="pass")
            cached = "cached" if ext.get("recording_cached") else f"written in {num(ext.get('recording_s'), '.1f')} s"
            rows.append(
                [
                    Cell(cid),
                    Cell(section[:-1]),
                    status,
                    Cell(str(ext.get("exit_code", NULL))),
                    Cell(num(ext.get("wall_s"), ".2f")),
                    Cell(num(ext.get("cpu_s"), ".2f")),
                    Cell(num(ext.get("peak_rss_mb"), ".0f")),
                    Cell(f"{ext.get('recording')} ({cached})", css="text"),
                    Cell(str(ext.get("output", NULL)), css="text"),
                ]
            )
    if not rows:
        return []
    note = (
        "Command components: an executable run on the scenario's recording after the built-ins, its trajectory read back "
        "under the declared contract and scored in the tables above. Wall, CPU (user + system, its child processes "
        "included) and peak memory are the command's own, apart from the bench's in the header; the recording is written "
        "once per setup into a cache and reused. Its stdout and stderr are in commands/<id>.stdout.log and .stderr.log."
    )
    header = ["component", "scored as", "status", "exit code", "wall (s)", "CPU (s)", "peak memory (MB)", "recording", "output"]
    return [Heading(2, "Command components"), Table(header, rows, note)]


def gps(ctx: Context) -> list:
    """The receiver: availability, shares, HDOP, and its true error split into open-sky and environment-added."""
    g = ctx.metrics.get("gps")
    if not g:
        return []
    shares = Table(
        ["fixes (count)", "measured", "valid (incl. dead reckoning)", "blackout", "NLOS share", "HDOP median", "faulty (> 5 m)"],
        [
            [
                Cell(str(g.get("fixes", NULL))),
                Cell(share(g.get("availability"))),
                Cell(share(g.get("valid"))),
                Cell(share(g.get("blackout"))),
                Cell(share(g.get("nlos_share"))),
                Cell(num(g.get("hdop_median"), ".2f")),
                Cell(share(g.get("faulty_5m"))),
            ]
        ],
        "Shares of all fixes (NLOS share and faulty: of the measured ones); HDOP is dimensionless.",
    )
    keys = ("rmse", "mean", "median", "p95", "max")
    errors = Table(
        ["horizontal error of measured fixes (m)", *keys],
        [
            [Cell(label)] + [Cell(metres((g.get(node) or {}).get(k))) for k in keys]
            for node, label in (("error", "true error"), ("open_sky_error", "open-sky part"), ("added_error", "added by the environment"))
        ],
    )
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
        cells = [
            Cell(str(kind)),
            Cell(num(w["start"][i] - ctx.t0, ".1f")),
            Cell(num(w["end"][i] - ctx.t0, ".1f")),
            Cell(num(w["duration"][i], ".1f")),
        ]
        cells += [Cell(passage_text(w[f"{e}.max_error"][i], w[f"{e}.exit_error"][i], w[f"{e}.recover_s"][i])) for e in eids]
        rows.append(cells)
    note = (
        "Times in seconds since the first scan. Per estimator: the worst horizontal error in the window / at its end, "
        "in metres, and (in brackets) how long after the window it took to come back within 1 m of its error at entry "
        "(never: not by the end of the run)."
    )
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
