"""Would the cn0 monitor refuse fewer good fixes if it weighed each suspect satellite by how far it can move the fix?

The cn0 monitor (fusion/monitors/cn0.py) refuses a whole fix when any one used satellite's C/N0 falls gate_sigma below
the template: around the Charles River the trees' crowns attenuate direct signals (sim.GnssReceiver's
foliage_loss_db_per_m), and one attenuated satellite among a four-constellation fix's 15-18 refuses it, though it moves
the fix by little. This prints, against the truth, the monitor's verdicts beside a geometric rule: the fix is refused
when its suspects (deficit > gate_sigma) could together move it by more than the fault threshold, each by its slope (the
horizontal shift of the least-squares fix per metre of range bias, from the reported azimuths and elevations, equal
weights) times an NLOS bias of B metres, held over the monitor's hold_s. Slopes with one receiver clock and with one clock
per constellation (as a multi-GNSS receiver estimates its inter-system biases).

Per library scenario and seed, its [fast] stretch's GNSS fixes alone (as benchmarks/cn0_satellites.py: no LiDAR, a
closed-loop scenario sailed open loop), each screened and judged as an estimator does (check, then commit). A fix is
faulty when the environment added more than --fault-m to its horizontal error (truth error less the open-sky receiver's,
the library's monitor.added_5m); recall is the share of faulty fixes refused, false alarms the share of the others refused.

    .venv/bin/python benchmarks/cn0_geometry.py [--scenarios charles_river canal_multipath] [--seeds 0 1 2] [--bias-m 20 30 40]
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


def slopes(el_deg: np.ndarray, az_deg: np.ndarray, systems: list[str], clock_per_system: bool) -> np.ndarray:
    """Horizontal shift (m) of the equally weighted least-squares fix per metre of range bias on each satellite."""
    el, az = np.deg2rad(el_deg), np.deg2rad(az_deg)
    line_of_sight = np.stack([np.cos(el) * np.sin(az), np.cos(el) * np.cos(az), np.sin(el)], axis=1)
    clocks = sorted(set(systems)) if clock_per_system else [None]
    clock = np.array([[1.0 if key in (None, system) else 0.0 for key in clocks] for system in systems])
    H = np.hstack([-line_of_sight, clock])
    try:
        S = np.linalg.solve(H.T @ H, H.T)
    except np.linalg.LinAlgError:
        return np.full(len(el), np.inf)
    return np.hypot(S[0], S[1])


def stream(name: str, seed: int, fault_m: float, bias_m: list[float]) -> dict[str, list[int]]:
    """Per rule [faulty refused, faulty, good refused, good] over one stretch's judged fixes."""
    scenario = scenarios.load(name, seed=seed).fast_variant()
    if scenario.control.mode != "open_loop":
        scenario = scenario.model_copy(update={"control": scenario.control.model_copy(update={"mode": "open_loop"})})
    run = assemble(scenario)
    monitor = monitors.create("cn0")
    rules = ["cn0"] + [f"B {b:g} m, {clocks}" for b in bias_m for clocks in ("1 clock", "clock per system")]
    counts = {rule: [0, 0, 0, 0] for rule in rules}
    recent: list[tuple[float, np.ndarray]] = []  # (stamp, each geometric rule's statistic) within hold_s
    for t in run.receiver.epochs(run.t_end, run.t_start):
        fix = run.receiver.fix(run.vessel_run.world, run.trajectory, float(t))
        obs = screen(fix, UERE_M, False)[0]
        if obs is None:
            continue
        judged = monitor.satellite_deficits(obs)
        verdict = monitor.check(obs, None)
        monitor.commit(obs, verdict)
        if isinstance(judged, str) or fix.truth is None:
            continue
        deficit, used, _, _ = judged
        suspect = deficit > monitor.gate
        el, az = np.array([s.el_deg for s in used], float), np.array([s.az_deg for s in used], float)
        systems = [str(getattr(s, "system", "GPS")) for s in used]
        shift = [slopes(el, az, systems, per)[suspect].sum() for per in (False, True)]
        statistic = np.array([b * s for b in bias_m for s in shift])
        recent = [(stamp, v) for stamp, v in recent if obs.stamp - monitor.params.hold_s <= stamp] + [(obs.stamp, statistic)]
        held = np.max([v for _, v in recent], axis=0)
        added = float(np.hypot(*(np.asarray(fix.truth.error)[:2] - np.asarray(fix.truth.open_sky_error)[:2])))
        if not math.isfinite(added):
            continue
        faulty = added > fault_m
        refused = [not verdict.trusted, *(held > fault_m)]
        for rule, r in zip(rules, refused):
            counts[rule][0 if faulty else 2] += bool(r)
            counts[rule][1 if faulty else 3] += 1
    return counts


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="*", default=["charles_river", "busy_waterway", "dam_lock", "canal_multipath"])
    parser.add_argument("--seeds", nargs="*", type=int, default=[0, 1, 2])
    parser.add_argument("--fault-m", type=float, default=5.0, help="environment-added error that makes a fix faulty, m [5]")
    parser.add_argument("--bias-m", nargs="*", type=float, default=[20.0, 30.0, 40.0], help="NLOS range bias assumed per suspect, m")
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
            for rule, c in stream(name, seed, args.fault_m, args.bias_m).items():
                total[rule] = total.get(rule, np.zeros(4, dtype=int)) + c
        for rule, (caught, faulty, alarms, good) in total.items():
            recall = f"{caught / faulty:.3f}" if faulty else "-"
            false_alarms = f"{alarms / good:.3f}" if good else "-"
            print(f"| {name} | {rule} | {faulty} | {recall} | {good} | {false_alarms} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
