"""Which test refuses the good fixes: an estimator's false alarms over run directories, by the rule that refused them.

Issue 39's goal is at most 5% false alarms (measured fixes the environment moved by 5 m or less that the monitor refused)
in every scenario; the library's runs give 15-80%. Each refused fix names its rule in gps.csv (`<id>.rule`: cn0.deficit,
cn0.hold, consistency.guard, consistency.window, consistency.walk, consistency.reference, joined by + when several members refused), so
this prints, per scenario and seed found under the given directories (a `riverbench suite --out DIR`, or run
directories), the estimator's false-alarm rate and each rule's share of it, then each rule's false alarms and caught faults pooled over the runs.

    .venv/bin/riverbench suite --fast --seeds 2 --out runs/fa
    .venv/bin/python benchmarks/false_alarms.py runs/fa [--estimator ekf]
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

from scenarios.report import plots
from scenarios.report.refusals import by_rule


def run_dirs(roots: list[Path]) -> list[Path]:
    """Every run directory (one holding gps.csv and metrics.json) under the roots, sorted."""
    return sorted({p.parent for root in roots for p in root.rglob("gps.csv") if (p.parent / "metrics.json").exists()})


def label(run: Path, roots: list[Path]) -> str:
    """The run's path below its root (a suite's <scenario>/seed-<n>), or its name."""
    for root in roots:
        if run.is_relative_to(root) and run != root:
            return str(run.relative_to(root))
    return run.name


def fail(message: str) -> None:
    """Bad input: one line on stderr, exit 2."""
    print(f"error: {message}", file=sys.stderr)
    sys.exit(2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("roots", nargs="+", type=Path, help="run directories or directories holding them")
    parser.add_argument("--estimator", default="ekf", help="estimator id [ekf]")
    args = parser.parse_args()
    missing = [str(r) for r in args.roots if not r.is_dir()]
    if missing:
        fail(f"not a directory: {missing[0]}")
    runs = run_dirs(args.roots)
    if not runs:
        fail(f"no run directory (gps.csv and metrics.json) under {', '.join(map(str, args.roots))}")
    pooled: Counter[str] = Counter()
    caught: Counter[str] = Counter()
    pooled_good = scored = 0
    print(f"{args.estimator}: false alarms by the rule that refused them (share of the run's good measured fixes)")
    print(f"{'run':<40} {'good':>6} {'FA':>6}  rules")
    for run in runs:
        counts, good = by_rule(plots.read_csv(run / "gps.csv"), args.estimator)
        if good is None:
            print(f"{label(run, args.roots):<40} {'–':>6} {'–':>6}  no {args.estimator}.rule column or no truth")
            continue
        fa = sum(c.false_alarms or 0 for c in counts)
        parts = ", ".join(f"{c.rule} {c.false_alarms / good:.3f}" for c in counts if c.false_alarms and good)
        print(f"{label(run, args.roots):<40} {good:>6} {fa / good if good else float('nan'):>6.3f}  {parts}")
        pooled.update({c.rule: c.false_alarms or 0 for c in counts})
        caught.update({c.rule: c.caught or 0 for c in counts})
        pooled_good += good
        scored += 1
    total = sum(pooled.values())
    print(f"\npooled over {scored} runs: {total} false alarms of {pooled_good} good fixes ({total / max(pooled_good, 1):.3f})")
    print(f"  {'rule':<40} {'false alarms':>12} {'of good':>8} {'of FA':>6} {'caught':>7}")
    for rule in sorted(set(pooled) | set(caught), key=lambda r: (-pooled[r], -caught[r], r)):
        n = pooled[rule]
        print(f"  {rule:<40} {n:>12} {n / max(pooled_good, 1):>8.3f} {n / max(total, 1):>6.1%} {caught[rule]:>7}")
    print(f"  (caught: refused fixes the environment moved by more than 5 m; {sum(caught.values())} in all)")


if __name__ == "__main__":
    main()
