"""The cn0 monitor weighing its suspect satellites by how far they can move the fix, against the truth, at several NLOS biases.

The cn0 monitor (fusion/monitors/cn0.py) refuses a fix only when its suspects (deficit > gate_sigma) could together move
it by more than fault_m: each by its slope (fusion.monitors.satellite_geometry: the horizontal shift of the receiver's
elevation-weighted least-squares fix per metre of range bias, one clock per constellation) times nlos_bias_m, or (the
default, vertical_reflectors) nlos_bias_m cos(elevation), the extra path off a vertical wall. Around the
Charles River the trees' crowns attenuate direct signals (sim.GnssReceiver's foliage_loss_db_per_m); unweighed
(nlos_bias_m 0, the monitor before 2026-12) one attenuated satellite among a four-constellation fix's 15-18 refused it,
though it moves the fix by little. This prints the monitor's recall and false alarms unweighed and at each --bias-m,
with and without the cos(elevation), and (--per-satellite-gate) with every satellite tested at gate_sigma, as before the
gate held for the fix (family_gate, Sidak 1967).

Per library scenario and seed, its [fast] stretch's GNSS fixes alone (as benchmarks/cn0_satellites.py: no LiDAR, a
closed-loop scenario sailed open loop), each screened and judged as an estimator does (check, then commit). A fix is
faulty when the environment added more than --fault-m to its horizontal error (truth error less the open-sky receiver's,
the library's monitor.added_5m); recall is the share of faulty fixes refused, false alarms the share of the others refused.

    .venv/bin/python benchmarks/cn0_geometry.py [--scenarios charles_river canal_multipath] [--seeds 0 1 2] [--bias-m 25 50 100]
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

import scenarios
from fusion import monitors
from fusion.observation import screen
from scenarios.pipeline.assembly import assemble

UERE_M = 3.0


def stream(name: str, seed: int, fault_m: float, bias_m: list[float], per_satellite: bool) -> dict[str, list[int]]:
    """Per monitor [faulty refused, faulty, good refused, good] over one stretch's judged fixes."""
    scenario = scenarios.load(name, seed=seed).fast_variant()
    if scenario.control.mode != "open_loop":
        scenario = scenario.model_copy(update={"control": scenario.control.model_copy(update={"mode": "open_loop"})})
    run = assemble(scenario)
    judges = {"unweighed (nlos_bias_m 0)": monitors.create("cn0", nlos_bias_m=0.0, fault_m=fault_m)}
    judges |= {f"nlos_bias_m {b:g}": monitors.create("cn0", nlos_bias_m=b, fault_m=fault_m, vertical_reflectors=False) for b in bias_m}
    judges |= {f"nlos_bias_m {b:g} cos(el) (default)": monitors.create("cn0", nlos_bias_m=b, fault_m=fault_m) for b in bias_m}
    if per_satellite:
        per = {f"nlos_bias_m {b:g} cos(el), per-satellite gate": dict(nlos_bias_m=b, fault_m=fault_m, family_gate=False) for b in bias_m}
        judges |= {rule: monitors.create("cn0", **params) for rule, params in per.items()}
    counts = {rule: [0, 0, 0, 0] for rule in judges}
    for t in run.receiver.epochs(run.t_end, run.t_start):
        fix = run.receiver.fix(run.vessel_run.world, run.trajectory, float(t))
        obs = screen(fix, UERE_M, False)[0]
        if obs is None:
            continue
        verdicts = {rule: monitor.check(obs, None) for rule, monitor in judges.items()}
        for rule, monitor in judges.items():
            monitor.commit(obs, verdicts[rule])
        if fix.truth is None or any(math.isnan(v.statistic) for v in verdicts.values()):
            continue
        added = float(np.hypot(*(np.asarray(fix.truth.error)[:2] - np.asarray(fix.truth.open_sky_error)[:2])))
        if not math.isfinite(added):
            continue
        faulty = added > fault_m
        for rule, verdict in verdicts.items():
            counts[rule][0 if faulty else 2] += not verdict.trusted
            counts[rule][1 if faulty else 3] += 1
    return counts


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="*", default=["charles_river", "busy_waterway", "dam_lock", "canal_multipath"])
    parser.add_argument("--seeds", nargs="*", type=int, default=[0, 1, 2])
    parser.add_argument("--fault-m", type=float, default=5.0, help="environment-added error that makes a fix faulty, m [5]")
    parser.add_argument("--bias-m", nargs="*", type=float, default=[25.0, 50.0, 100.0], help="NLOS range biases to weigh the suspects with, m")
    parser.add_argument(
        "--per-satellite-gate", action="store_true", help="also judge each satellite at gate_sigma (family_gate false, the gate before 2026-12-08)"
    )
    args = parser.parse_args()
    try:
        for name in args.scenarios:
            scenarios.load(name)  # an unknown scenario is refused before anything runs
        if min([args.fault_m, *args.bias_m]) <= 0:
            raise ValueError(f"--fault-m and --bias-m must be positive, got {args.fault_m} and {args.bias_m}")
    except ValueError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"fault: environment-added horizontal error > {args.fault_m:g} m; [fast] stretches, seeds {args.seeds}")
    print("| scenario | rule | faulty fixes | recall | good fixes | false alarms |")
    print("|---|---|---:|---:|---:|---:|")
    for name in args.scenarios:
        total: dict[str, np.ndarray] = {}
        for seed in args.seeds:
            for rule, c in stream(name, seed, args.fault_m, args.bias_m, args.per_satellite_gate).items():
                total[rule] = total.get(rule, np.zeros(4, dtype=int)) + c
        for rule, (caught, faulty, alarms, good) in total.items():
            recall = f"{caught / faulty:.3f}" if faulty else "-"
            false_alarms = f"{alarms / good:.3f}" if good else "-"
            print(f"| {name} | {rule} | {faulty} | {recall} | {good} | {false_alarms} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
