"""The cn0 monitor with and without the satellites' levels (fusion/monitors/cn0.py, 'Between satellites') on the library's
simulated fixes: the verdicts must be the same, to the last bit, since the simulator's satellites share one C/N0 model.

Per library scenario and seed, its [fast] stretch's GNSS fixes alone (scenarios.pipeline.assembly builds the receiver,
world and trajectory; no LiDAR; a closed-loop scenario is sailed on its planned route, which its driven one follows), each
screened and judged as an estimator does (check, then commit) by two fresh monitors: 'cn0' and 'cn0' with
satellite_levels false. Printed per stream: fixes judged, fixes whose verdict, statistic or reason differ, the largest
ratio of the satellites' levels' spread to what it must exceed to widen sigma (the margin: > 1 would switch), and the
recall and false-alarm rate of the default monitor against the truth (a fix is NLOS-affected when it used a satellite
received only by reflection).

    .venv/bin/python benchmarks/cn0_satellites.py [--scenarios quickstart canal_multipath] [--seeds 0 1 2 3 4]
"""

from __future__ import annotations

import argparse
import math

import scenarios
from fusion import monitors
from fusion.observation import screen
from scenarios.pipeline.assembly import assemble

UERE_M = 3.0


def same(a, b) -> bool:
    """Two verdicts alike to the last bit (NaN statistics alike)."""
    nan = math.isnan(a.statistic) and math.isnan(b.statistic)
    return (a.trusted, a.reason) == (b.trusted, b.reason) and (a.statistic == b.statistic or nan)


def stream(name: str, seed: int) -> dict:
    """Judge one stretch's fixes with and without the satellites' levels."""
    scenario = scenarios.load(name, seed=seed).fast_variant()
    if scenario.control.mode != "open_loop":
        scenario = scenario.model_copy(update={"control": scenario.control.model_copy(update={"mode": "open_loop"})})
    run = assemble(scenario)
    levels, bins = monitors.create("cn0"), monitors.create("cn0", satellite_levels=False)
    out = {"judged": 0, "differ": 0, "margin": 0.0, "nlos": 0, "caught": 0, "clean": 0, "alarms": 0}
    for t in run.receiver.epochs(run.t_end, run.t_start):
        fix = run.receiver.fix(run.vessel_run.world, run.trajectory, float(t))
        obs = screen(fix, UERE_M, False)[0]
        if obs is None:
            continue
        a, b = levels.check(obs, None), bins.check(obs, None)
        levels.commit(obs, a), bins.commit(obs, b)
        out["differ"] += not same(a, b)
        if levels.between_satellites is not None:
            spread, switch = levels.between_satellites
            out["margin"] = max(out["margin"], spread / switch)
        if math.isnan(a.statistic):
            continue
        out["judged"] += 1
        nlos = fix.truth is not None and any(t.nlos and s.used for t, s in zip(fix.truth.sats, fix.sats))
        out["nlos" if nlos else "clean"] += 1
        out["caught" if nlos else "alarms"] += not a.trusted
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="*", default=None, help="library scenarios [all]")
    parser.add_argument("--seeds", nargs="*", type=int, default=[0], help="seeds [0]")
    args = parser.parse_args()
    names = args.scenarios or scenarios.available()
    print("| scenario | seed | judged | differing verdicts | largest levels' spread / switch | NLOS fixes | recall | clean fixes | false alarms |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    differ = 0
    for name in names:
        for seed in args.seeds:
            r = stream(name, seed)
            differ += r["differ"]
            recall = r["caught"] / r["nlos"] if r["nlos"] else math.nan
            alarms = r["alarms"] / r["clean"] if r["clean"] else math.nan
            print(
                f"| {name} | {seed} | {r['judged']} | {r['differ']} | {r['margin']:.2f} | {r['nlos']} | {recall:.3f} | {r['clean']} | {alarms:.3f} |"
            )
    print(f"\nfixes whose verdict differs with the satellites' levels: {differ}")


if __name__ == "__main__":
    main()
