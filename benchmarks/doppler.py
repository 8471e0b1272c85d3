"""How good the receiver's velocity over ground is (sim.doppler): its horizontal error against the antenna's true velocity,
over the library's GNSS stretches, by HDOP and by whether the fix used a satellite received only by reflection.

Receivers measure velocity from Doppler; its open-sky error is the data sheets' 0.05 m/s at the median (u-blox NEO-M8N,
ZED-F9P), and a reflected satellite adds its extra path's rate of change. The fused ekf uses a fix's velocity when the
monitor trusts the fix and its HDOP is at most 2.5 (fusion.ekf.EkfParams.gps_velocity_max_hdop); this prints the error
where it does and where it does not.

    .venv/bin/python benchmarks/doppler.py [--scenarios open_river quickstart canal_multipath dam_lock] [--seed 0]
"""

from __future__ import annotations

import argparse
import math

import numpy as np

import scenarios
from scenarios.pipeline.assembly import assemble

HDOP_BINS = (0.0, 1.0, 1.5, 2.5, 5.0, 100.0)
STEP_S = 1e-3
"""The antenna's true velocity by central differences over this step (sim.gnss differences over the same)."""


def velocity_errors(name: str, seed: int) -> dict[str, np.ndarray]:
    """Per measured fix of the scenario's [fast] stretch: horizontal velocity error (m/s), HDOP, and whether a used
    satellite was received only by reflection (the truth)."""
    scenario = scenarios.load(name).fast_variant().model_copy(update={"seed": seed})
    stack = assemble(scenario)
    receiver, trajectory, world = stack.receiver, stack.trajectory, stack.vessel_run.world
    offset = np.array(receiver.config.antenna_offset_m)
    error, hdop, nlos = [], [], []
    for t in receiver.epochs(stack.t_end - STEP_S, stack.t_start + STEP_S):
        fix = receiver.fix(world, trajectory, float(t))
        if fix.quality not in (1, 2, 4, 5) or not math.isfinite(fix.speed_mps):
            continue
        before, after = (trajectory.pose(float(t) + d) for d in (-STEP_S, STEP_S))
        truth = ((after[:3, :3] @ offset + after[:3, 3]) - (before[:3, :3] @ offset + before[:3, 3]))[:2] / (2.0 * STEP_S)
        course = math.radians(fix.course_deg)
        reported = fix.speed_mps * np.array([math.sin(course), math.cos(course)])
        error.append(float(np.linalg.norm(reported - truth)))
        hdop.append(fix.hdop)
        nlos.append(any(s.nlos and r.used for s, r in zip(fix.truth.sats, fix.sats)))
    return {"error": np.array(error), "hdop": np.array(hdop), "nlos": np.array(nlos, dtype=bool)}


def line(label: str, error: np.ndarray) -> str:
    if not len(error):
        return f"  {label:28s} n 0"
    p50, p95 = np.percentile(error, [50, 95])
    return f"  {label:28s} n {len(error):5d}  median {p50:.3f}  p95 {p95:.3f}  max {error.max():.3f} m/s"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenarios", nargs="+", default=["open_river", "quickstart", "canal_multipath", "dam_lock"])
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    for name in args.scenarios:
        e = velocity_errors(name, args.seed)
        print(f"{name} (seed {args.seed}, [fast] where it has one)")
        print(line("all measured fixes", e["error"]))
        print(line("no reflected satellite used", e["error"][~e["nlos"]]))
        print(line("a reflected satellite used", e["error"][e["nlos"]]))
        for lo, hi in zip(HDOP_BINS[:-1], HDOP_BINS[1:]):
            print(line(f"HDOP {lo:g}-{hi:g}", e["error"][(e["hdop"] >= lo) & (e["hdop"] < hi)]))


if __name__ == "__main__":
    main()
