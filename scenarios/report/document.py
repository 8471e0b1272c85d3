"""The report document: blocks (headings, paragraphs, tables, figures) and their two renderings, Markdown and one
self-contained HTML page; what the run, comparison and replay reports are built of."""

from __future__ import annotations

import base64
import html
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

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
    ranked_if: Callable[[dict], bool] | None = None  # a row whose value is shown but not ranked when this says False


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


def ranked_table(first: str, nodes: dict[str, dict], columns: list[Column], labels: dict[str, str], note: str = "") -> Table:
    """A row per node, a cell per column; the best value of each ranked column in bold (none when all equal)."""
    texts = {c.title: {k: c.fmt(c.value(n)) for k, n in nodes.items()} for c in columns}
    best = {c.title: _best_text(c, nodes) for c in columns}
    rows = [
        [Cell(labels[k], css="fail" if n.get("failed") else "")]
        + [
            Cell(
                texts[c.title][k] + (c.detail(n) if c.detail else ""),
                bold=texts[c.title][k] == best[c.title] and _ranked(c, n),
                css="text" if c.text else "",
            )
            for c in columns
        ]
        for k, n in nodes.items()
    ]
    return Table([first, *(c.title for c in columns)], rows, note)


def _ranked(column: Column, node: dict) -> bool:
    """Whether the node's value competes for best in the column."""
    return column.ranked_if is None or column.ranked_if(node)


def _best_text(column: Column, nodes: dict[str, dict]) -> str | None:
    """The printed best value of a ranked column among the rows it ranks, or None when unranked or when no value stands out."""
    values = [v for v in (column.value(n) for n in nodes.values() if _ranked(column, n)) if v is not None and v == v]
    if column.better is None or len({column.fmt(v) for v in values}) < 2:
        return None
    return column.fmt(min(values) if column.better == "low" else max(values))


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

    lines = [
        "| " + " | ".join(h.replace("|", "\\|") for h in table.header) + " |",
        "|" + "|".join([":---"] + ["---:"] * (len(table.header) - 1)) + "|",
    ]
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
            body.append(
                f'<figure><img src="data:image/png;base64,{data}" alt="{html.escape(b.caption)}">'
                f"<figcaption>{html.escape(b.caption)}</figcaption></figure>"
            )
    return (
        f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n<title>{html.escape(title)}</title>\n'
        f"<style>{CSS}</style>\n</head>\n<body>\n" + "\n".join(body) + "\n</body>\n</html>\n"
    )


def _html_table(table: Table) -> str:
    """An HTML table in a horizontally scrolling box, and its note."""

    def cell(c: Cell) -> str:
        """One <td>: escaped, bold when best, classed pass/fail/text."""
        text = html.escape(c.text)
        text = f"<b>{text}</b>" if c.bold else text
        return f'<td class="{c.css}">{text}</td>' if c.css else f"<td>{text}</td>"

    text_columns = {i for row in table.rows for i, c in enumerate(row) if c.css == "text"}
    head = "".join(
        f'<th class="text">{html.escape(h)}</th>' if i in text_columns else f"<th>{html.escape(h)}</th>" for i, h in enumerate(table.header)
    )
    rows = "".join("<tr>" + "".join(cell(c) for c in row) + "</tr>\n" for row in table.rows)
    note = f'<p class="note">{html.escape(table.note)}</p>' if table.note else ""
    return f'<div class="scroll"><table>\n<tr>{head}</tr>\n{rows}</table></div>{note}'
