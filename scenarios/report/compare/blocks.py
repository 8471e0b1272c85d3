"""The comparison report's blocks: header, summary, a section per configuration, the runs compared and those that did not finish."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

from scenarios.report import document, plots, stanford
from scenarios.report import run_report as report
from scenarios.report.compare import figures
from scenarios.report.compare.groups import (
    ACCURACY,
    APE_ALIGNED,
    APE_P95,
    FALSE_ALARMS,
    FAULTY,
    HZ,
    MATCHER,
    MONITOR,
    RECALL,
    SUCCESS,
    WINDOWS,
    Configuration,
    Spread,
    failed,
    spread_of,
)
from scenarios.report.compare.roc import ZOOM_FA, roc_figure, roc_path
from scenarios.report.compare.runs import Unfinished, plural
from scenarios.report.compare.verdicts import conf_sentences, overall_sentences
from scenarios.report.document import NULL, Cell, Column, Heading, Image, Table, Text
from scenarios.score.metrics import FAULT_M

SPREAD_NOTE = (
    "Median over seeds (min–max over seeds) of the runs in which the component did not fail (failed runs are counted "
    "apart); bold: best median in its column."
)


def seeds_text(seeds: list[int | None]) -> str:
    """The seeds as a range when consecutive ('0–4'), else listed."""
    known = sorted({s for s in seeds if s is not None})
    if len(known) > 2 and known == list(range(known[0], known[-1] + 1)):
        return f"{known[0]}–{known[-1]}"
    return ", ".join(map(str, known)) or NULL


def build(confs: list[Configuration], images: dict[str, str], stopped: list[Unfinished], out_dir: Path) -> list:
    """Every block of the comparison report, in reading order."""
    return [
        *header(confs),
        *summary_section(confs, images),
        *(b for conf in confs for b in conf_section(conf, images)),
        *unfinished_section(stopped, out_dir),
        *runs_section(confs, out_dir),
    ]


def header(confs: list[Configuration]) -> list:
    """Title and what was compared: runs, scenarios, configurations, seeds."""
    runs = [r for c in confs for r in c.runs]
    names = sorted({c.scenario for c in confs})
    per = sorted({len(c.runs) for c in confs})
    meta = (
        f"{plural(len(runs), 'run')} · {plural(len(names), 'scenario')} ({', '.join(names)}) · {plural(len(confs), 'configuration')} · "
        f"seeds {seeds_text([r.seed for r in runs])} ({'–'.join(map(str, (per[0], per[-1]) if len(per) > 1 else per))} per configuration)"
    )
    return [
        Heading(1, "riverbench comparison"),
        Text(meta, "meta"),
        Text(
            "Each number is the median over the seeds of a configuration, in brackets the range (min–max) over those seeds. "
            "A difference is called clear when the two ranges do not overlap; with one seed the spread is unknown.",
            "note",
        ),
    ]


def summary_section(confs: list[Configuration], images: dict[str, str]) -> list:
    """The written summary over all configurations, the APE figures, then the cross-scenario tables."""
    return [Heading(2, "Summary"), *(Text(s) for s in overall_sentences(confs)), *ape_blocks(images), *summary_blocks(confs)]


def ape_blocks(images: dict[str, str]) -> list:
    """The APE figures (estimators, matchers) that were drawn, captioned under one heading (none drawn: nothing)."""
    captions = {
        "estimators": "Each estimator's APE p95 (horizontal, m) in each configuration",
        "matchers": "Each matcher's odometry APE rmse after the best-fit planar motion (aligned, m) in each configuration",
    }
    drawn = [
        Image(
            images[figures.APE_KEY + kind],
            f"{caption}: dot at the median over the seeds in which it did not fail, bar from "
            "their min to max, printed on the right; sorted lowest first within a configuration; a logarithmic axis when the values "
            "span more than 30 times.",
        )
        for kind, caption in captions.items()
        if figures.APE_KEY + kind in images
    ]
    return [Heading(3, "APE per component and configuration"), *drawn] if drawn else []


def summary_blocks(confs: list[Configuration]) -> list:
    """Estimators' APE p95 and matchers' success, aligned APE rmse and Hz: a row per component, a column per configuration."""
    blocks = [Heading(3, "Estimators: APE p95 (m)"), cross_table("estimator", confs, "estimators", APE_P95)]
    if any(r.config.get("control", {}).get("mode") == "closed_loop" for c in confs for r in c.runs):
        blocks += [Heading(3, "Vessel: clearance and collisions"), vessel_table(confs)]
    if any(c.matchers for c in confs):
        for title, column in (("Matchers: success", SUCCESS), ("Matchers: aligned APE rmse (m)", APE_ALIGNED), ("Matchers: speed (Hz)", HZ)):
            blocks += [Heading(3, title), cross_table("matcher", confs, "matchers", column)]
    return blocks


def spread_text(s: Spread | None, fmt: Callable) -> str:
    """' (lo–hi)' after a median, or nothing with fewer than two values."""
    return f" ({fmt(s.lo)}–{fmt(s.hi)})" if s is not None and s.n > 1 else ""


def spread_column(
    title: str, base: Column, locate: Callable[[dict], dict], failures: bool = False, ranked_if: Callable[[dict], bool] | None = None
) -> Column:
    """A column over aggregated nodes: `locate` finds the component's node, whose Spread under base's title is ranked by
    its median (among the nodes `ranked_if` admits) and printed with its range."""

    def median(node: dict) -> float | None:
        """The median, ranked and printed first."""
        s = locate(node).get(base.title)
        return None if s is None else s.median

    def detail(node: dict) -> str:
        """The range over seeds, and with `failures` how many runs failed."""
        mine = locate(node)
        text = spread_text(mine.get(base.title), base.fmt)
        return text + (f" [{mine['failures']} of {mine['runs']} runs failed]" if failures and mine.get("failures") else "")

    return Column(title, median, base.fmt, base.better, detail=detail, ranked_if=ranked_if)


def _recall_above_zero(node: dict) -> bool:
    """Whether a monitor's median recall is above 0: its false-alarm rate is ranked only then (flagging nothing is no merit)."""
    recall = node.get(RECALL.title)
    return recall is not None and recall.median > 0


def _itself(node: dict) -> dict:
    """A per-configuration table's node is the component's own."""
    return node


FAILURE_COLUMN = Column(
    "failure rate",
    lambda n: n["failures"] / n["runs"] if n["runs"] else None,
    document.share,
    None,
    detail=lambda n: f" ({n['failures']}/{n['runs']})",
)
"""Share of a configuration's runs in which the component failed (not ranked: no failure is no merit)."""


def cross_table(first: str, confs: list[Configuration], kind: str, base: Column) -> Table:
    """A row per configuration, a column per component id: the base metric's median over seeds with its range; the
    row's best in bold (who wins where reads along a row)."""
    ids = list(dict.fromkeys(cid for c in confs for cid in getattr(c, kind)))
    rows = []
    for conf in confs:
        nodes = getattr(conf, kind)
        spreads = {cid: nodes.get(cid, {}).get(base.title) for cid in ids}
        medians = {cid: s.median for cid, s in spreads.items() if s is not None and s.median == s.median}
        texts = {cid: base.fmt(medians.get(cid)) for cid in ids}
        best = None
        if base.better and len({texts[c] for c in medians}) > 1:
            best = texts[(min if base.better == "low" else max)(medians, key=medians.get)]
        cells = [document.Cell(conf.title, css="text")]
        for cid in ids:
            node = nodes.get(cid, {})
            failed = f" [{node['failures']} of {node['runs']} runs failed]" if node.get("failures") else ""
            cells.append(document.Cell(texts[cid] + spread_text(spreads[cid], base.fmt) + failed, bold=texts[cid] == best))
        rows.append(cells)
    return Table(["scenario", *ids], rows, SPREAD_NOTE.replace("best median in its column", "best median in its row"))


VESSEL_COLUMNS = (
    ("min clearance (m)", "min_clearance_m"),
    ("s within threshold", "time_below_threshold_s"),
    ("cross-track max (m)", "cross_track.max"),
)


def vessel_table(confs: list[Configuration]) -> Table:
    """A row per configuration: what the vessel was steered on, its collisions over the runs, its closest approach and cross-track error."""
    rows = []
    for conf in confs:
        nodes = [r.metrics.get("vessel", {}) for r in conf.runs]
        control = conf.runs[0].config.get("control", {})
        steering = control.get("steer_on", NULL) if control.get("mode") == "closed_loop" else "open loop"
        hits = sum(bool(n.get("collisions")) for n in nodes)
        cells = [Cell(conf.title, css="text"), Cell(str(steering)), Cell(f"{hits} of {len(nodes)}", css="fail" if hits else None)]
        for _, path in VESSEL_COLUMNS:
            spread = spread_of([document.get(path)(n) for n in nodes])
            cells.append(Cell(NULL if spread is None else document.metres(spread.median) + spread_text(spread, document.metres)))
        rows.append(cells)
    note = (
        "Median over seeds (min–max). Clearance: the hull's distance to the nearest structure (0 after a collision); "
        "time within the scenario's clearance threshold; cross-track: the true offset from the route."
    )
    return Table(["scenario", "steered on", "collisions", *(title for title, _ in VESSEL_COLUMNS)], rows, note)


def conf_section(conf: Configuration, images: dict[str, str]) -> list:
    """One configuration: what it is, who wins, the ranked tables and the monitors' ROC."""
    info = conf.runs[0].config
    blocks: list = [Heading(2, conf.title)]
    if info.get("description"):
        blocks.append(Text(str(info["description"])))
    blocks.append(
        Text(
            f"world {info.get('world', NULL)} · stretch {report.stretch_text(info.get('stretch') or {})} · "
            f"{plural(len(conf.runs), 'run')}, seeds {seeds_text([r.seed for r in conf.runs])}",
            "meta",
        )
    )
    blocks += [Text(s) for s in conf_sentences(conf)]
    blocks += error_blocks(conf, images)
    blocks += estimator_tables(conf) + matcher_tables(conf) + roc_blocks(conf, images) + stanford_blocks(conf, images)
    return blocks


def error_blocks(conf: Configuration, images: dict[str, str]) -> list:
    """The configuration's error-against-time figure, or nothing when no run holds a component's poses."""
    key = figures.ERROR_KEY + conf.title
    if key not in images:
        return []
    caption = (
        f"Horizontal error against time of each component over {plural(len(conf.runs), 'run')}: estimators (their estimate "
        "against the truth) and matchers (their odometry after the best-fit planar motion, as its aligned APE); a line per "
        "component at the median over seeds, each seed faintly behind it; GPS-degradation windows (blackout under bridges, "
        "NLOS beside walls, re-acquisition after a blackout) of any of the runs shaded."
    )
    return [Heading(3, "Error against time"), Image(images[key], caption)]


def stanford_blocks(conf: Configuration, images: dict[str, str]) -> list:
    """The configuration's Stanford diagram (its runs' epochs pooled), or nothing when no estimator reported a level."""
    key = STANFORD_KEY + conf.title
    if key not in images:
        return []
    caption = (
        f"Stanford diagram over the scans of {plural(len(conf.runs), 'run')}, pooled: each estimator's horizontal error against "
        "the protection level it reported, coloured by epochs per cell; above the diagonal the level failed to bound the error "
        "(misleading information), above the dashed alert limit while the level was inside it, hazardously."
    )
    return [Heading(3, "Protection levels"), Image(images[key], caption)]


STANFORD_KEY = "stanford:"
"""Prefix of a configuration's Stanford diagram among the drawn images (the ROC is keyed by the title alone)."""


def draw_stanfords(confs: list[Configuration], out_dir: Path) -> dict[str, str]:
    """Draw each configuration's Stanford diagram where its runs hold levels; returns {STANFORD_KEY + title: relative path}."""
    written = {}
    for index, conf in enumerate(confs):
        pooled: dict[str, list] = {}
        alert = float((conf.runs[0].config.get("integrity") or {}).get("alert_limit_m", plots.RunSeries.alert_limit_m))
        for run in conf.runs:
            series = plots.load(run.path, list(conf.estimators), [], {})
            for eid in conf.estimators:
                if (e := plots.stanford_epochs(series, eid)) is not None:
                    pooled.setdefault(eid, []).append(e)
        epochs = {eid: stanford.Epochs.pooled(parts) for eid, parts in pooled.items()}
        figure = stanford.figure(epochs, alert, conf.title, plots.WIDTH_IN)
        if figure is None:
            continue
        path = roc_path(index, conf.title).replace("plots/roc-", "plots/stanford-")
        (out_dir / path).parent.mkdir(parents=True, exist_ok=True)
        figure.savefig(out_dir / path, format="png", dpi=plots.DPI)
        written[STANFORD_KEY + conf.title] = path
    return written


def estimator_tables(conf: Configuration) -> list:
    """Availability and accuracy with the failure rate, then worst errors through GPS degradation and the monitor's scores."""
    nodes = conf.estimators
    if not nodes:
        return []
    labels = {cid: cid for cid in nodes}
    accuracy = document.ranked_table(
        "estimator",
        nodes,
        [*(spread_column(c.title, c, _itself) for c in ACCURACY), FAILURE_COLUMN],
        labels,
        "Available: share of a run's scans with an estimate (an estimator that starts late has less, and its errors cover "
        "fewer scans); errors: horizontal, in metres, over those scans; RPE: mean error per 100 m of true travel; yaw: heading "
        "error in degrees; failure rate: share of runs in which the estimator failed. " + SPREAD_NOTE,
    )
    windows = [c for c in WINDOWS if any(n.get(c.title) for n in nodes.values())]
    monitored = any(n.get("monitor_kind", "none") != "none" for n in nodes.values())
    blocks = [Heading(3, "Estimators"), accuracy]
    if windows or monitored:
        columns = [spread_column(c.title, c, _itself) for c in windows]
        notes = []
        if windows:
            notes.append("Worst horizontal error (m) inside any window of that kind (blackout: under bridges; NLOS: reflected signals beside walls).")
        if monitored:
            columns += [MONITOR, spread_column(FAULTY.title, FAULTY, _itself), spread_column(RECALL.title, RECALL, _itself)]
            columns.append(spread_column(FALSE_ALARMS.title, FALSE_ALARMS, _itself, ranked_if=_recall_above_zero))
            notes.append(
                "Monitor: faulty fixes: measured fixes with more than 5 m added by the environment; recall: the share of those "
                "it flagged (– when there were none); false alarms: the share of the other measured fixes it flagged, ranked "
                "only beside a median recall above 0 (flagging nothing is no merit)."
            )
        blocks.append(document.ranked_table("estimator", nodes, columns, labels, " ".join([*notes, SPREAD_NOTE])))
    return blocks


def matcher_tables(conf: Configuration) -> list:
    """Success, degeneracy, speed, points and odometry accuracy of each matcher, with its failure rate."""
    if not conf.matchers:
        return []
    columns = [*(spread_column(c.title, c, _itself) for c in MATCHER), FAILURE_COLUMN]
    note = (
        "Success: share of scans with a usable match; degenerate: usable matches with an unobserved direction; Hz and time: "
        "wall-clock rate and 95th-percentile time per registered scan; points: per scan; errors (m) of the odometry chained "
        "from the true start, APE aligned after the best-fit planar motion; yaw in degrees. " + SPREAD_NOTE
    )
    return [Heading(3, "Scan matchers"), document.ranked_table("matcher", conf.matchers, columns, {cid: cid for cid in conf.matchers}, note)]


def roc_blocks(conf: Configuration, images: dict[str, str]) -> list:
    """The ROC figure, or why there is none."""
    if conf.title in images:
        caption = (
            f"Monitor ROC over the {conf.roc.measured} measured fixes of {plural(len(conf.runs), 'run')}, pooled: recall (share of the "
            f"{conf.roc.faulty} fixes with more than {FAULT_M:g} m added by the environment that are flagged) against false-alarm rate "
            f"(share of the others flagged), linear axes, each threshold of the monitor's statistic; dot: its actual verdicts, which can "
            f"lie off the curve (a combined monitor, a hold after an alarm, fixes refused before initialisation). "
            f"Right: false-alarm rates up to {ZOOM_FA:.0%}."
        )
        return [Heading(3, "Monitor ROC"), Image(images[conf.title], caption)]
    why = (
        f"No measured fix had more than {FAULT_M:g} m added by the environment"
        if not conf.roc.faulty
        else "No estimator here has a monitor with a statistic"
    )
    return [Heading(3, "Monitor ROC"), Text(f"{why}: no ROC curve.")]


def draw_rocs(confs: list[Configuration], out_dir: Path) -> dict[str, str]:
    """Draw the ROC figure of each configuration with faulty fixes and a monitor; returns {configuration title: relative path}."""
    written = {}
    for index, conf in enumerate(confs):
        if conf.roc.curves:
            path = roc_path(index, conf.title)
            (out_dir / path).parent.mkdir(parents=True, exist_ok=True)
            roc_figure(conf.title, conf.roc, list(conf.estimators), len(conf.runs)).savefig(out_dir / path, format="png", dpi=plots.DPI)
            written[conf.title] = path
    return written


def unfinished_section(stopped: list[Unfinished], out_dir: Path) -> list:
    """Suite cases and sweep runs that left no run directory (none: no section)."""
    if not stopped:
        return []
    rows = [[Cell(u.scenario, css="fail"), Cell(u.reason, css="text"), Cell(_relative(u.suite_file, out_dir), css="text")] for u in stopped]
    return [Heading(2, "Runs that did not finish"), Table(["scenario", "reason", "listed in"], rows, "These runs are in no table above.")]


def _relative(path: Path, out_dir: Path) -> str:
    """A path relative to the report's directory."""
    return os.path.relpath(Path(path).absolute(), Path(out_dir).absolute())


def runs_section(confs: list[Configuration], out_dir: Path) -> list:
    """Every run compared: configuration, seed, hash, path, expectations passed, each failed expectation with its value
    and threshold, failed components."""
    rows = []
    for conf in confs:
        for run in conf.runs:
            outcomes = run.metrics.get("expectations") or []
            passed = sum(bool(o.get("pass")) for o in outcomes)
            missed = [failed_expectation(o) for o in outcomes if not o.get("pass")]
            broken = [cid for kind in ("estimators", "matchers") for cid in run.metrics.get(kind) or {} if failed(run, kind, cid)]
            rows.append(
                [
                    Cell(conf.title, css="text"),
                    Cell(NULL if run.seed is None else str(run.seed)),
                    Cell(run.hash or NULL),
                    Cell(_relative(run.path, out_dir), css="text"),
                    Cell(f"{passed}/{len(outcomes)}", css=("pass" if passed == len(outcomes) else "fail") if outcomes else ""),
                    Cell("; ".join(missed), css="fail" if missed else "text"),
                    Cell(", ".join(broken), css="fail" if broken else "text"),
                ]
            )
    note = (
        "Paths relative to this report. Failed expectations: the metric (a dotted path of the run's metrics.json), its value "
        "and the bound it missed; failed components: estimators and matchers that failed during the run."
    )
    return [
        Heading(2, "Runs"),
        Table(["configuration", "seed", "hash", "path", "expectations passed", "failed expectations", "failed components"], rows, note),
    ]


def failed_expectation(outcome: dict) -> str:
    """'estimators.ekf.ape.p95 = 9.12 (expected < 8.4)': a failed expectation's metric, value and bound (or why it has no value)."""
    path, op, bound = (str(outcome.get("expect", "")).split() + ["", "", ""])[:3]
    value = outcome.get("value")
    if value is None or value != value:
        return f"{outcome.get('expect', NULL)}: {outcome.get('reason') or 'no value'}"
    return f"{path} = {value:.4g} (expected {op} {bound})"
