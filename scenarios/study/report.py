"""The study report: the verdict table, then each finding's checks and figure; report.md and a self-contained
report.html built from the same blocks as the run report (scenarios.report.document), written atomically."""

from __future__ import annotations

from pathlib import Path

from riverbench.atomic import atomic_path
from scenarios.report.document import Cell, Heading, Image, Table, Text, to_html, to_markdown
from scenarios.study import plots
from scenarios.study.verdicts import VERDICTS

VERDICT_CSS = {"agrees": "pass", "disagrees": "fail", "partly": "", "unmeasured": ""}


def blocks(tree: dict, images: dict[str, str]) -> list:
    """Every block of the report, in reading order."""
    sc, plan, run = tree["scenario"], tree["plan"], tree.get("run", {})
    prov = tree["provenance"]
    out: list = [
        Heading(1, "riverbench study: the field study's findings on the bench"),
        Text(tree["citation"], "meta"),
        Text(
            f"scenario {sc['name']} (seed {sc['seed']}, hash {sc['hash']}"
            + "".join(f", --set {o}" for o in sc.get("overrides", []))
            + f"), {sc['t_start']:.0f}-{sc['t_end']:.0f} s of the route; "
            f"{plan['bursts']} bursts of {plan['burst_scans']} revolutions every {plan['burst_spacing_s']:g} s (pcl6d on 1 in "
            f"{plan['pcl6d_every']}), {plan['chain_scans']} revolutions chained (1 in {plan['chain_stride']}); "
            f"measured in {run.get('measure_wall_s', 0.0):.0f} s "
            f"on {run.get('workers', '?')} processes; riverbench {prov.get('riverbench')} {prov.get('git_commit', '')[:10]}",
            "meta",
        ),
        Heading(2, "Setups"),
        *[Text(f"{name}: {setup['description']}.") for name, setup in tree.get("setups", {}).items()],
        Heading(2, "Verdicts"),
        Table(
            ["finding", "the study", "setup", "the bench", "verdict", "cause"],
            [
                [
                    Cell(f"{k}. {f['title']}", css="text"),
                    Cell(f["claim"], css="text"),
                    Cell(name, css="text"),
                    Cell(node["headline"], css="text"),
                    Cell(node["verdict"], css=VERDICT_CSS[node["verdict"]]),
                    Cell(node.get("cause", ""), css="text"),
                ]
                for k, f in tree["findings"].items()
                for name, node in _rows(f)
            ],
            note=f"verdict: agrees when every check of the finding holds, disagrees when none does, partly otherwise ({', '.join(VERDICTS)}); "
            "each rule is in scenarios/study/verdicts.py, each cause's mechanism in scenarios/study/causes.py; "
            + "; ".join(f"{name}: {n} of {len(tree['findings'])} agree" for name, n in agreeing(tree).items()),
        ),
    ]
    for k, f in tree["findings"].items():
        setups = _by_setup(f)
        out += [
            Heading(2, f"{k}. {f['title']}: " + ", ".join(f"{node['verdict']} ({name})" for name, node in setups.items())),
            Text(f"The study: {f['claim']}"),
        ]
        for name, node in setups.items():
            out += [
                Text(f"{name}: {node.get('cause', '')}"),
                _checks_table(node, f"the bench ({name})"),
            ]
        for cid, by_setup in f.get("components", {}).items():
            for name, node in by_setup.items():
                out += [
                    Text(f"{cid} (your command {tree['components'][cid]['section'][:-1]}), {name}: {node['headline']}"),
                    _checks_table(node, f"{cid} ({name})"),
                ]
        if k in images:
            out.append(Image(images[k], plots.CAPTIONS[k]))
    if tree.get("components"):
        out += command_blocks(tree["components"])
    return out


def _rows(f: dict) -> list[tuple[str, dict]]:
    """The verdict table's rows of one finding: each setup's, then each command component's under each setup."""
    rows = list(_by_setup(f).items())
    for cid, by_setup in f.get("components", {}).items():
        rows += [(f"{name}: {cid} (command)", node) for name, node in by_setup.items()]
    return rows


def command_blocks(commands: dict) -> list:
    """The command components: what ran, where its run directory is, what it cost and how it scored as in a run."""
    rows = []
    for cid, c in commands.items():
        for name, r in c["runs"].items():
            ext = r.get("external", {})
            ape = r.get("ape", {}).get("rmse")
            rows.append(
                [
                    Cell(cid, css="text"),
                    Cell(c["section"][:-1], css="text"),
                    Cell(name, css="text"),
                    Cell(", ".join(c["findings"]) or "none", css="text"),
                    Cell(f"failed: {r['reason']}" if r["failed"] else "ok", css="fail" if r["failed"] else "pass"),
                    Cell("" if r["failed"] else f"{r.get('coverage', float('nan')):.3f}"),
                    Cell("" if ape is None else f"{ape:.3f}"),
                    Cell(f"{ext.get('wall_s', float('nan')):.1f}"),
                    Cell(f"{ext.get('cpu_s', float('nan')):.1f}"),
                    Cell(f"{ext.get('peak_rss_mb', float('nan')):.0f}"),
                    Cell(f"{ext.get('recording_s', float('nan')):.1f}" + (" (cached)" if ext.get("recording_cached") else "")),
                    Cell(r["run_dir"], css="text"),
                ]
            )
    return [
        Heading(2, "Command components"),
        Text(
            'Your components of kind = "command", each run once on a recording of the stretch (matchers under the first setup, '
            "estimators under each) and scored as in `riverbench run`; their run directories hold metrics.json, the trajectories, "
            "the command's logs under commands/. Each finding above judges them apart from the built-ins (scenarios/study/components.py)."
        ),
        Table(
            [
                "id",
                "kind",
                "setup",
                "findings",
                "outcome",
                "coverage",
                "APE rmse (m)",
                "wall (s)",
                "CPU (s)",
                "peak MB",
                "recording (s)",
                "run directory",
            ],
            rows,
            note="APE rmse: a matcher's after its declared anchor, an estimator's in the map; wall, CPU and memory: the command's own",
        ),
    ]


def _by_setup(f: dict) -> dict:
    """The finding's node per setup (a study.json without setups: its one node, as the bench's)."""
    return f.get("setups") or {"bench": f}


def agreeing(tree: dict) -> dict[str, int]:
    """How many findings agree under each setup."""
    counts: dict[str, int] = {}
    for f in tree["findings"].values():
        for name, node in _by_setup(f).items():
            counts[name] = counts.get(name, 0) + (node["verdict"] == "agrees")
    return counts


def _checks_table(node: dict, measured_by: str) -> Table:
    """A finding's checks under one setup: the claim, the study's figure, the measured one (column `measured_by`), held."""
    rows = [
        [Cell(c["claim"], css="text"), Cell(c["study"], css="text"), Cell(c["measured"], css="text"), Cell(_holds(c["holds"]), css=_css(c["holds"]))]
        for c in node["checks"]
    ]
    return Table(["check", "the study", measured_by, "holds"], rows)


def _holds(value: bool | None) -> str:
    return "no data" if value is None else "yes" if value else "no"


def _css(value: bool | None) -> str:
    return "" if value is None else "pass" if value else "fail"


def write(study_dir: Path, tree: dict, samples) -> None:
    """plots/*.png, report.md and report.html into the (temporary) study directory."""
    images = plots.write_all(study_dir / "plots", tree, samples)
    doc = blocks(tree, images)
    for name, text in (("report.md", to_markdown(doc)), ("report.html", to_html(doc, study_dir, title="riverbench study"))):
        with atomic_path(study_dir / name) as tmp:
            tmp.write_text(text, encoding="utf-8")
