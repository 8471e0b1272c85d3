"""A replay's report: report.md, report.html and plots/map.png from its run directory, in the blocks and renderers of scenarios.report.run_report.

There is no truth: without a reference the estimators are compared with the GPS fixes their own
monitors trusted (agreement with GPS, which has its own error, not accuracy: the report's first
line says so); with one (`--reference`) they are scored against it. The matchers are judged by
what they report about themselves. A GNSS-only replay (no LiDAR) says so in its first lines.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from riverbench.atomic import atomic_path
from scenarios.report import document, plots, run_report, world_map
from scenarios.report.document import Cell, Column, Heading, Table, Text, get, metres, num, share

MAP = "plots/map.png"
WORLD_PAD_M = 30.0
"""How far around the recording's fixes and tracks the world is drawn, plus a tenth of their span."""
MAP_CAPTION = (
    "The recording in the world's ENU frame over the scenario world's parts (when the recording lies on it): GPS fixes (grey: measured, "
    "brown: dead reckoning), each estimate, and each matcher's odometry (dashed)."
)
ESTIMATOR_COLUMNS = [
    Column("available", get("available"), share, "high"),
    Column("trusted fixes", get("against_gps.trusted"), share, None),
    Column("compared (fixes)", get("against_gps.fixes"), lambda v: num(v, ".0f"), None),
    Column("to GPS rmse (m)", get("against_gps.rmse"), metres, None),
    Column("to GPS median (m)", get("against_gps.median"), metres, None),
    Column("to GPS p95 (m)", get("against_gps.p95"), metres, None),
    Column("to GPS max (m)", get("against_gps.max"), metres, None),
    Column("position from (s)", get("startup.position_s"), lambda v: num(v, ".1f"), None),
    Column("heading from (s)", get("startup.heading_s"), lambda v: num(v, ".1f"), None),
    Column("heading by", lambda node: node.get("startup", {}).get("heading_from"), lambda v: str(v or "–"), None, text=True),
]
REFERENCE_COLUMNS = [
    Column("available", get("against_reference.available"), share, "high"),
    Column("scored (fixes)", get("against_reference.scored"), lambda v: num(v, ".0f"), None),
    Column("APE rmse (m)", get("against_reference.ape.rmse"), metres),
    Column("APE median (m)", get("against_reference.ape.median"), metres),
    Column("APE p95 (m)", get("against_reference.ape.p95"), metres),
    Column("APE max (m)", get("against_reference.ape.max"), metres),
    Column("blackouts", get("against_reference.blackout.count"), lambda v: num(v, ".0f"), None),
    Column("blackout max (m)", get("against_reference.blackout.max_error"), metres),
    Column("blackout exit (m)", get("against_reference.blackout.exit_error"), metres),
]
MATCHER_TITLES = ("success", "gated", "Hz", "time p95 (ms)", "points (median)", "degenerate")
MATCHER_COLUMNS = [c for c in run_report.MATCHER_COLUMNS if c.title in MATCHER_TITLES]


def write(run_dir: Path) -> None:
    """Write plots/map.png, report.md and report.html into a finished replay directory."""
    run_dir = Path(run_dir)
    tree = json.loads((run_dir / "metrics.json").read_text())
    images = {MAP: MAP_CAPTION} if draw_map(run_dir, tree) else {}
    blocks = build(tree, images)
    title = f"riverbench replay: {Path(tree['run']['recording']['path']).name}"
    for name, text in (("report.md", document.to_markdown(blocks)), ("report.html", document.to_html(blocks, run_dir, title))):
        with atomic_path(run_dir / name) as tmp:
            tmp.write_text(text, encoding="utf-8")


def build(tree: dict, images: dict[str, str]) -> list:
    """Every block of the report, in reading order."""
    ctx = run_report.Context(tree, {}, images, 0.0, {})
    blocks = [*header(tree), *run_report.failures(ctx)]
    estimators = tree.get("estimators", {})
    if estimators and "reference" in tree:
        ref = tree["reference"]
        note = (
            f"Horizontal error (m) of each estimate's {'antenna' if ref['point'] == 'antenna' else 'base_link'} against the reference, "
            "interpolated to the times the estimates were sampled; available: share of those times with an estimate; blackout: "
            "the worst error inside or at the exit of the recording's GPS blackouts (no measured fix)."
        )
        blocks += [
            Heading(2, "Estimators against the reference"),
            document.ranked_table("estimator", estimators, REFERENCE_COLUMNS, labels(estimators), note),
        ]
    if estimators:
        note = (
            "No truth: horizontal distance (m) from each estimate's antenna, interpolated to the fix time, to the measured GPS "
            "fixes its own monitor trusted (their share: trusted fixes). GPS has its own error: this is agreement with it, "
            "not accuracy. Start-up: when each estimator first had a position and a heading (s after the recording's start) "
            "and what gave the heading: motion (GPS travel, with the odometry when there is some), a compass, the receiver's "
            "course over ground, or nothing yet: a vessel at rest starts on its position alone."
        )
        blocks += [Heading(2, "Estimators against GPS"), document.ranked_table("estimator", estimators, ESTIMATOR_COLUMNS, labels(estimators), note)]
    blocks += [*run_report.figures(ctx, "map"), *gps(tree.get("gps", {}))]
    matchers = tree.get("matchers", {})
    if matchers:
        note = (
            "Success: share of scans after the first with a usable match; gated: dropped by the point-count gate; Hz and time: "
            "wall-clock rate and 95th-percentile time per registered scan; points: per scan; degenerate: usable matches with an "
            "unobserved direction."
        )
        blocks += [Heading(2, "Scan matchers"), document.ranked_table("matcher", matchers, MATCHER_COLUMNS, labels(matchers), note)]
    return blocks


def header(tree: dict) -> list:
    """Title; what the scores mean (agreement with GPS, or accuracy against a reference); GNSS-only or not; what was replayed
    through what, its sensor, time base, clocks and ENU origin, what was dropped or skipped, how fast it ran, where matcher
    odometry starts, and warnings."""
    run, rec = tree["run"], tree["run"]["recording"]
    lat, lon = rec["origin"][:2]
    digits = ".2f" if (run["duration_s"] or 0) < 100 else ".1f"
    ref = tree.get("reference")
    if ref is None:
        scoring = (
            "No reference: the estimators are scored by their distance to the GPS fixes their own monitors trusted: agreement with "
            "GPS, not accuracy (give --reference FILE to score accuracy)."
        )
    else:
        scoring = (
            f"Scored against the reference {Path(ref['path']).name} ({ref['format']}, {ref['samples']} samples of the {ref['point']}): "
            "accuracy, within the reference's own error."
        )
    blocks = [Heading(1, f"riverbench replay: {Path(rec['path']).name}"), Text(scoring, "note")]
    if run.get("gnss_only"):
        blocks.append(
            Text(
                "GNSS-only replay: the recording has no LiDAR, so the estimators ran without a matcher (no odometry); their poses "
                f"were read after each of the {run['fixes']} fixes.",
                "note",
            )
        )
    scans = f"{run['fixes']} GPS fixes (no scans)" if run.get("gnss_only") else f"{run['scans']} scans · {run['fixes']} GPS fixes"
    what = f"{rec['format']} · lidar: {rec['lidar'] or 'none'} · GPS: {rec['gps']}"
    blocks.append(Text(f"scenario {run['scenario']} ({run['scenario_hash']}) · {what}", "meta"))
    if rec.get("sensor_note"):
        blocks.append(Text(f"sensor: {rec['sensor_note']}", "meta"))
    clocks = rec.get("clocks")
    timeline = f" on the {clocks['timeline']}" if clocks else ""
    blocks.append(
        Text(
            f"time zero {rec['time_zero_utc']}{timeline} · ENU origin {lat:.6f}, {lon:.6f} ({rec['origin_from']}) · "
            f"t = {num(run['t_start'], digits)} … {num(run['t_end'], digits)} s",
            "meta",
        )
    )
    if clocks:
        pairs = (("capture − sensor", "capture_minus_sensor_s"), ("sensor − GNSS", "sensor_minus_gnss_s"), ("capture − GNSS", "capture_minus_gnss_s"))
        offsets = [f"{name} {num(clocks[key], '+.3f')} s" for name, key in pairs if clocks.get(key) is not None]
        measured = f" (GNSS offsets from {clocks['gnss_offsets_from']})" if clocks.get("gnss_offsets_from") else ""
        blocks.append(Text(f"clocks: {', '.join(offsets)}{measured}; PPS {clocks['pps']}", "meta"))
    if "revolutions" in rec:
        blocks.append(
            Text(
                f"{rec['revolutions']} whole revolutions replayed, {rec['partial_revolutions_dropped']} partial ones dropped · "
                f"{run['fixes']} of the {rec['fixes_in_file']} GPRMC fixes in the file read",
                "meta",
            )
        )
    if "nmea" in rec:
        blocks.append(Text(f"NMEA: {rec['nmea']['summary']}", "meta"))
    blocks.append(
        Text(
            f"{num(run['duration_s'], digits)} s of recording in {num(run['wall_s'], '.1f')} s "
            f"({num(run['realtime_factor'], '.1f')}× real time; opening it took {num(run.get('read_s'), '.1f')} s, starting "
            f"{run['workers']} process(es) {num(run.get('startup_s'), '.1f')} s) · {scans} · peak memory {num(run['peak_rss_mb'], '.0f')} MB",
            "meta",
        )
    )
    anchor = run.get("anchor")
    if anchor and not run.get("gnss_only"):
        heading = {"estimate": "its heading", "course over ground": "its course over ground", "none": "no heading known: its position only"}
        where = f"{anchor['estimator']} at t = {num(anchor['t'], digits)} s"
        blocks.append(Text(f"matcher odometry laid on {where} ({heading[anchor['heading']]})", "meta"))
    blocks += [Text(f"warning: {warning}", "meta") for warning in run.get("warnings", [])]
    return blocks


def labels(nodes: dict[str, dict]) -> dict[str, str]:
    """Row labels: the id, and when it failed."""
    return {k: f"{k} (failed at {num(n.get('failed_at'), '.1f')} s)" if n.get("failed") else k for k, n in nodes.items()}


def gps(g: dict) -> list:
    """The receiver's fix qualities and HDOP as recorded."""
    if not g:
        return []
    return [
        Heading(2, "GPS"),
        Table(
            ["fixes (count)", "measured", "valid", "dead reckoning", "HDOP median"],
            [
                [
                    Cell(str(g.get("fixes"))),
                    Cell(share(g.get("measured"))),
                    Cell(share(g.get("valid"))),
                    Cell(share(g.get("dead_reckoning"))),
                    Cell(num(g.get("hdop_median"), ".2f")),
                ]
            ],
            "Shares of all fixes; HDOP is dimensionless.",
        ),
    ]


def world_patches(ax, run_dir: Path, tree: dict, fixes: dict, tracks: dict) -> list:
    """The scenario's world under the map when the replay's ENU frame is the world's (legend patches; none otherwise)."""
    if tree["run"]["recording"].get("origin_from") != "world" or not (run_dir / "scenario.toml").exists():
        return []
    world = world_map.load(tomllib.loads((run_dir / "scenario.toml").read_text()))
    x = np.concatenate([fixes.get("e", np.zeros(0)), *(t.x for t in tracks.values())])
    y = np.concatenate([fixes.get("n", np.zeros(0)), *(t.y for t in tracks.values())])
    keep = np.isfinite(x) & np.isfinite(y)
    if world is None or not keep.any():
        return []
    pad = WORLD_PAD_M + 0.1 * max(np.ptp(x[keep]), np.ptp(y[keep]))
    extent = (x[keep].min() - pad, x[keep].max() + pad, y[keep].min() - pad, y[keep].max() + pad)
    return world_map.draw(ax, world_map.footprints(world, extent))


def draw_map(run_dir: Path, tree: dict) -> bool:
    """Draw plots/map.png (False when there is nothing to draw)."""
    fixes = plots.read_csv(run_dir / "gps.csv")
    tracks = {k: plots.read_tum(run_dir / f"{k}.tum") for k in [*tree.get("estimators", {}), *tree.get("matchers", {})]}
    if not len(fixes.get("t", [])) and not any(len(t.t) for t in tracks.values()):
        return False
    figure = Figure(figsize=(plots.WIDTH_IN, 7.0), layout="constrained")
    ax = figure.subplots()
    world = world_patches(ax, run_dir, tree, fixes, tracks)
    for quality, (label, colour) in plots.QUALITY_STYLE.items():
        keep = fixes.get("quality", np.zeros(0)) == quality
        if keep.any():
            ax.scatter(fixes["e"][keep], fixes["n"][keep], s=12, color=colour, alpha=0.7, lw=0, label=label, zorder=5)
    for i, (name, track) in enumerate(tracks.items()):
        style = "--" if name in tree.get("matchers", {}) else "-"
        ax.plot(track.x, track.y, style, color=plots.TRACK_COLOURS[i % len(plots.TRACK_COLOURS)], lw=1.4, label=name, zorder=4)
    ax.set_aspect("equal", adjustable="datalim")
    ax.ticklabel_format(useOffset=False, style="plain")
    ax.set_xlabel("east (m)")
    ax.set_ylabel("north (m)")
    ax.grid(alpha=0.3)
    about = {"world": "the world's origin", "first fix": "the first fix"}.get(tree["run"]["recording"]["origin_from"], "its origin")
    ax.set_title(f"The recording in ENU metres about {about}: GPS fixes, estimates, matcher odometry", fontsize=10)
    handles, names = ax.get_legend_handles_labels()
    ax.legend(handles + world, names + [str(p.get_label()) for p in world], loc="best", fontsize=9)
    with atomic_path(run_dir / MAP) as tmp:
        figure.savefig(tmp, format="png", dpi=plots.DPI)
    return True
