"""Findings a-d of `riverbench study` under three receiver classes and several seeds: which class reproduces which.

The study's receiver is not named; the field setup takes the era's GPS-only L1 receiver (`sbas_gps`). Findings a (an
outage under every deck) and b (a wrong estimate after an outage) pull the receiver's class different ways, and this
prints by how much: the receiver alone over the whole charles_river route (every epoch, its filter running on, as
`riverbench study` drives it), per class and seed, the verdicts of a-d and their figures: b's share of outages whose
first 10 fixes are off by more than open water's p95, the median time back within it, how many of those outages end on
fixes that use a satellite received only by its reflection (the truth), and a's share of the epochs without a measured
fix under each deck. About a minute per receiver and seed on one core.

    .venv/bin/python benchmarks/study_receivers.py [--seeds 0,1,2]
"""

from __future__ import annotations

import argparse

from scenarios.pipeline.assembly import assemble
from scenarios.study import gnss_findings, tasks, verdicts
from scenarios.study.findings import by_key
from scenarios.study.plan import study_scenario

RECEIVERS: dict[str, dict | None] = {
    "sbas, four systems (bench)": None,
    "sbas_gps, GPS alone (field)": {"profile": "sbas_gps"},
    "sbas_gps + GLONASS": {"profile": "sbas_gps", "constellations": ["GPS", "GLONASS"]},
}
"""The receiver classes: the library's, the field setup's, and the era's other common class (GLONASS has been fully
operational since 2011; receivers tracking GPS and GLONASS, such as the u-blox M8 of 2014, were common by 2016)."""


def seeds(text: str) -> list[int]:
    """--seeds: comma-separated non-negative integers (argparse names a bad value in one line, exit 2)."""
    try:
        values = [int(s) for s in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give comma-separated seeds, e.g. 0,1,2") from None
    if any(v < 0 for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: seeds are non-negative")
    return values


CHECKS = {"a": verdicts.checks_a, "b": verdicts.checks_b, "c": verdicts.checks_c, "d": verdicts.checks_d}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=seeds, default=[0, 1, 2], help="comma-separated seeds (default 0,1,2)")
    args = ap.parse_args()
    findings = by_key()
    print("| receiver | seed | a | b | c | d | b: wrong after | b: back within p95 (median) | b: ending on reflections | a: lost under each deck |")
    print("|:---|---:|:---|:---|:---|:---|---:|---:|---:|:---|")
    for seed in args.seeds:
        for name, receiver in RECEIVERS.items():
            scenario = study_scenario(seed=seed, receiver=receiver)
            structures = assemble(scenario).world.params.get("structures", [])
            measured = gnss_findings.measure(tasks.gnss(scenario), structures, 10)
            verdict = {k: verdicts.verdict(check(measured[k], findings[k])) for k, check in CHECKS.items()}
            b = measured["b"]
            rows = b["outages"]
            reflected = sum(r["first_reflected"] > 0 for r in rows)
            lost = ", ".join(f"{deck} {100 * s['lost_share_under']:.0f}%" for deck, s in measured["a"]["structures"].items())
            print(
                f"| {name} | {seed} | {verdict['a']} | {verdict['b']} | {verdict['c']} | {verdict['d']} | "
                f"{round(b['wrong_share'] * len(rows))} of {len(rows)} | {b['settle_s_median']:.1f} s | {reflected} of {len(rows)} | {lost} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
