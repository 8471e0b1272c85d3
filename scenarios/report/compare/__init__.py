"""The algorithm comparison report: estimators and scan matchers across scenarios, configurations and seeds.

`write(sources, out_dir)` finds every run directory under the sources (a run, a suite or a sweep directory, at any
depth; hidden directories are runs in progress and are skipped), groups the runs by scenario and configuration (the
resolved scenario without its seed: runs that differ only in seed are repeats), and writes report.md, a self-contained
report.html and plots/*.png (APE per component and configuration, error against time, ROC, Stanford diagrams). Every
number is the median over a configuration's seeds with its range (min–max), so a reader can tell a real difference from
noise; the written summary says which differences exceed that range.

Modules: runs (finding and reading runs), groups (configurations and spreads over seeds), roc (monitor ROC), verdicts
(the written summary), figures (APE and error against time over seeds), blocks (the report's blocks, rendered by
scenarios.report.run_report).
"""

from __future__ import annotations

from pathlib import Path

from riverbench.atomic import atomic_dir
from scenarios.report import document
from scenarios.report.compare import blocks, figures, groups, runs, verdicts
from scenarios.report.compare.against import section as baseline_section
from scenarios.score.regression import Comparison


def write(sources: list[Path], out_dir: Path, against: Comparison | None = None) -> Path:
    """Write report.md, report.html (self-contained, images embedded as data: URIs) and plots/*.png into out_dir; return report.html.
    With `against` (the runs judged against a baseline) the page opens with what regressed, improved or changed."""
    out_dir = Path(out_dir)
    run_dirs, listings = runs.find(sources)
    if (out_dir / "metrics.json").exists():
        raise ValueError(f"{out_dir}: is a run directory (its own report would be replaced); write the comparison elsewhere")
    confs = groups.configurations([runs.read_run(p) for p in run_dirs])
    stopped = runs.unfinished(listings)
    with atomic_dir(out_dir) as tmp:
        images = figures.draw(confs, tmp) | blocks.draw_rocs(confs, tmp) | blocks.draw_stanfords(confs, tmp)
        page = blocks.build(confs, images, stopped, out_dir)
        if against is not None:
            page[3:3] = baseline_section(against)  # after the title, what was compared and how to read it
        (tmp / "report.md").write_text(document.to_markdown(page), encoding="utf-8")
        (tmp / "report.html").write_text(document.to_html(page, tmp, title="riverbench comparison"), encoding="utf-8")
    return out_dir / "report.html"


def write_against(comparison: Comparison, out_dir: Path) -> Path:
    """A comparison page of two stored baselines (no runs to show): report.md and report.html with the baseline section."""
    out_dir = Path(out_dir)
    page = [document.Heading(1, "riverbench: baseline against baseline"), *baseline_section(comparison)]
    with atomic_dir(out_dir) as tmp:
        (tmp / "report.md").write_text(document.to_markdown(page), encoding="utf-8")
        (tmp / "report.html").write_text(document.to_html(page, tmp, title="riverbench baseline comparison"), encoding="utf-8")
    return out_dir / "report.html"


def collect(sources: list[Path]) -> list[runs.RunInfo]:
    """Every run directory under the sources, read (bad input raises ValueError naming the path)."""
    return [runs.read_run(p) for p in runs.find(sources)[0]]


def summary_markdown(sources: list[Path]) -> str:
    """The cross-scenario summary tables (estimators' APE p95; matchers' success, aligned APE, Hz) as Markdown, e.g. for the README."""
    return document.to_markdown(blocks.summary_blocks(groups.configurations(collect(sources))))


def summary_sentences(sources: list[Path]) -> list[str]:
    """The written summary over every configuration: who wins where, and whether by more than the spread."""
    return verdicts.overall_sentences(groups.configurations(collect(sources)))
