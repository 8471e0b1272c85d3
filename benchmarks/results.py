"""Regenerate every table of measured figures in docs/results.md and the README from the library's baseline.

    .venv/bin/python benchmarks/results.py [--baseline benchmarks/baseline/library.json] [--check]

The baseline comes from `riverbench suite --fast --seeds 5 --save-baseline benchmarks/baseline/library.json`
(see docs/guide.md, Regression baselines); each table is stamped with the commit and date it was measured at.
--check writes nothing and exits 1 when a generated file is out of date (what tests/test_results_fresh.py checks).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import scenarios
from riverbench.atomic import atomic_path
from scenarios.report.results import library_markdown, other_baseline_section, replace_block, results_markdown
from scenarios.score import baseline as baselines

ROOT = Path(__file__).resolve().parent.parent
BASELINE = ROOT / "benchmarks" / "baseline" / "library.json"


def library_checks(fast: bool, which: str) -> dict[str, list[str]]:
    """Each library scenario's expectations (which="expect") or goals (which="goals"), of the variant the baseline ran."""
    out = {}
    for name in scenarios.available():
        s = scenarios.load(name)
        out[name] = list(getattr(s.fast_variant() if fast else s, which))
    return out


def generated(baseline_path: Path = BASELINE) -> dict[Path, str]:
    """The text each generated file must have, from the baseline."""
    base = baselines.load(baseline_path)
    readme = ROOT / "README.md"
    results = results_markdown(base, library_checks(base.fast, "expect"), library_checks(base.fast, "goals"))
    for other in sorted(baseline_path.parent.glob("*.json")):
        if other.resolve() == Path(baseline_path).resolve():
            continue
        extra = baselines.load(other)
        title = f"{', '.join(sorted(extra.scenarios))} ({'fast variants' if extra.fast else 'full length'})"
        checks = library_checks(extra.fast, "expect"), library_checks(extra.fast, "goals")
        results += "\n" + other_baseline_section(title, str(other.relative_to(ROOT)), extra, *checks)
    return {ROOT / "docs" / "results.md": results, readme: replace_block(readme.read_text(encoding="utf-8"), library_markdown(base))}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, default=BASELINE)
    parser.add_argument("--check", action="store_true", help="write nothing; exit 1 when a file is out of date")
    args = parser.parse_args()
    stale = []
    for path, text in generated(args.baseline).items():
        current = path.read_text(encoding="utf-8") if path.exists() else ""
        if current == text:
            continue
        stale.append(path)
        if not args.check:
            with atomic_path(path) as tmp:
                tmp.write_text(text, encoding="utf-8")
    for path in stale:
        print(f"{'out of date' if args.check else 'wrote'}: {path.relative_to(ROOT)}")
    return 1 if args.check and stale else 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except ValueError as exc:  # a missing, corrupt or foreign baseline file: one line naming it
        print(f"error: {exc}", file=sys.stderr)
        sys.exit(2)
