"""Set every library expectation's bound from a baseline's spread over seeds (scenarios.report.results.derived_bound).

    .venv/bin/python benchmarks/expectations.py [benchmarks/baseline/library.json ...] [--write]

Prints each expectation with the baseline's values (median, min-max) and the derived bound; --write rewrites the
bounds in scenarios/spec/library/*.toml (the [fast] lists from a baseline of fast variants, the scenario's own list from
a baseline of full runs) and replaces the comment above each rewritten list, whose typed figures went stale, by a
pointer to docs/results.md. Commit the result with the baseline it came from; tests/test_library_expectations.py
then holds every bound at least that tight.
"""

from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

import scenarios
from scenarios.report.results import derived_bound, median_range
from scenarios.score import baseline as baselines
from scenarios.score.expectations import Expectation
from scenarios.spec.library import LIBRARY as library_dir

ROOT = Path(__file__).resolve().parent.parent
LIBRARY = library_dir
ITEM = re.compile(r'^(\s*)"([^"]+)"(,?)\s*$')


def rewrite(text: str, runs, fast_lists: bool, source: str) -> tuple[str, list[str]]:
    """The TOML text with the bounds of the chosen expect lists derived from `runs`, and a line per change."""
    lines = text.split("\n")
    section, inside, changes, lists = "", False, [], []
    for i, line in enumerate(lines):
        stripped = line.strip()
        if stripped.startswith("["):  # a table or an array of tables: [fast], [stretch], [[traffic.movers]]
            section = stripped.strip("[]")
        target = (section == "fast") if fast_lists else (section == "")
        if stripped.startswith("expect = ["):
            inside = target
            if target:
                lists.append(i)
            continue
        if inside and stripped.startswith("]"):
            inside = False
            continue
        m = ITEM.match(line)
        if inside and m:  # an item with a comment after it was bounded by hand and is left alone
            parsed = Expectation.parse(m.group(2))
            metric, op = parsed.path, parsed.op
            values = runs.values(metric, runs.seeds)
            bound = derived_bound(values, op, metric)
            if math.isnan(bound):
                continue
            new = f"{metric} {op} {bound:g}"
            if new != m.group(2):
                lines[i] = f'{m.group(1)}"{new}"{m.group(3)}'
                changes.append(f"{m.group(2)}  ->  {op} {bound:g}   ({median_range(values, '.3g')})")
    for i in reversed(lists):  # the comment above each rewritten list held typed figures: point to the generated ones
        j = i - 1
        while j >= 0 and lines[j].lstrip().startswith("#"):
            j -= 1
        lines[j + 1 : i] = [
            f"# expectations: bounds derived from the spread over seeds of {source} (benchmarks/expectations.py; values in docs/results.md)"
        ]
    return "\n".join(lines), changes


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("baselines", nargs="*", type=Path, default=[ROOT / "benchmarks" / "baseline" / "library.json"])
    parser.add_argument("--write", action="store_true", help="rewrite the bounds in scenarios/spec/library/*.toml")
    args = parser.parse_args()
    for path in args.baselines:
        path = path.resolve()
        base = baselines.load(path)
        source = str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else path.name
        for name, runs in sorted(base.scenarios.items()):
            if name not in scenarios.available():
                continue
            toml = LIBRARY / f"{name}.toml"
            has_fast = scenarios.load(name).fast is not None
            if not base.fast and not has_fast:
                continue  # a scenario without [fast] is judged by the fast baseline (the same run)
            text, changes = rewrite(toml.read_text(encoding="utf-8"), runs, base.fast and has_fast, source)
            for change in changes:
                print(f"{name}: {change}")
            if args.write and text != toml.read_text(encoding="utf-8"):
                toml.write_text(text, encoding="utf-8")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except ValueError as exc:  # a missing, corrupt or foreign baseline file: one line naming it
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
