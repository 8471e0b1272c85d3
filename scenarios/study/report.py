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
            f"scenario {sc['name']} (seed {sc['seed']}, hash {sc['hash']}), {sc['t_start']:.0f}-{sc['t_end']:.0f} s of the route; "
            f"{plan['bursts']} bursts of {plan['burst_scans']} revolutions every {plan['burst_spacing_s']:g} s (pcl6d on 1 in "
            f"{plan['pcl6d_every']}), {plan['chain_scans']} revolutions chained (1 in {plan['chain_stride']}); "
            f"measured in {run.get('measure_wall_s', 0.0):.0f} s "
            f"on {run.get('workers', '?')} processes; riverbench {prov.get('riverbench')} {prov.get('git_commit', '')[:10]}",
            "meta",
        ),
        Heading(2, "Verdicts"),
        Table(
            ["finding", "the study", "the bench", "verdict"],
            [
                [
                    Cell(f"{k}. {f['title']}", css="text"),
                    Cell(f["claim"], css="text"),
                    Cell(f["headline"], css="text"),
                    Cell(f["verdict"], css=VERDICT_CSS[f["verdict"]]),
                ]
                for k, f in tree["findings"].items()
            ],
            note=f"verdict: agrees when every check of the finding holds, disagrees when none does, partly otherwise ({', '.join(VERDICTS)}); "
            "each rule is in scenarios/study/verdicts.py",
        ),
    ]
    for k, f in tree["findings"].items():
        out += [
            Heading(2, f"{k}. {f['title']}: {f['verdict']}"),
            Text(f"The study: {f['claim']}"),
            Table(
                ["check", "the study", "the bench", "holds"],
                [
                    [
                        Cell(c["claim"], css="text"),
                        Cell(c["study"], css="text"),
                        Cell(c["measured"], css="text"),
                        Cell(_holds(c["holds"]), css=_css(c["holds"])),
                    ]
                    for c in f["checks"]
                ],
            ),
        ]
        if k in images:
            out.append(Image(images[k], plots.CAPTIONS[k]))
    return out


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
