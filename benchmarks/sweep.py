"""Sweep throughput on this machine: 1 against 2 local workers, the Ray backend against the local pool,
and a run inside a sweep against the same run alone.

    python benchmarks/sweep.py [--runs 8] [--seconds 30] [--repeats 1]

The sweep is canal_multipath on `--seconds` of its canyon with the LiDAR noise swept over
runs/2 values and 2 seeds. Each configuration writes into a fresh directory (nothing is skipped).
Prints wall times, runs per minute, the speed-up, and Ray's overhead per run.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from scenarios.batch.plan import Axis, SweepPlan
from scenarios.batch.sweep import run_sweep
from scenarios.pipeline.runner import run
from scenarios.spec.library import load


def plan(runs: int, seconds: float) -> SweepPlan:
    noise = ",".join(f"{0.01 + 0.005 * i:g}" for i in range(runs // 2))
    return SweepPlan(
        ("canal_multipath",),
        grid=(Axis.parse(f"lidar.range_noise_m={noise}"),),
        seeds=2,
        fixed=(f"stretch={{start_s = 60.0, end_s = {60.0 + seconds}}}",),
    )


def timed_sweep(p: SweepPlan, backend: str, workers: int) -> tuple[float, list[float]]:
    """Total wall time of the sweep and each run's own wall time."""
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        result = run_sweep(p, Path(tmp) / "sweep", workers=workers, backend=backend, lean=True)
        total = time.perf_counter() - start
    assert not result.failed, result.failed
    return total, [r["wall_s"] for r in result.rows]


def alone(p: SweepPlan, workers: int) -> float:
    """Wall time of the sweep's first run on its own (imports already paid), `workers` processes."""
    point = p.points()[0]
    scenario = load(point.source, set=list(point.assignments), seed=point.seed)
    with tempfile.TemporaryDirectory() as tmp:
        start = time.perf_counter()
        run(scenario, Path(tmp) / "run", workers=workers, report=False)
        return time.perf_counter() - start


def ray_start_s() -> float:
    """Seconds to start and stop a local Ray instance with 2 CPUs."""
    import ray

    start = time.perf_counter()
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, logging_level="ERROR")
    up = time.perf_counter() - start
    ray.shutdown()
    return up


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=8)
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args()
    p = plan(args.runs, args.seconds)
    n = len(p.points())
    print(f"{n} runs of canal_multipath, {args.seconds:g} s simulated each; median of {args.repeats} repeat(s)")
    print(f"one run alone: {alone(p, 1):.1f} s with 1 process, {alone(p, 2):.1f} s with 2")
    results = {}
    for backend, workers in (("local", 1), ("local", 2), ("ray", 2)):
        totals, per_run = [], []
        for _ in range(args.repeats):
            total, walls = timed_sweep(p, backend, workers)
            totals.append(total)
            per_run += walls
        results[(backend, workers)] = total = statistics.median(totals)
        print(
            f"{backend:5s} workers {workers}: {total:6.1f} s total, {60 * n / total:5.1f} runs/min, "
            f"a run inside: median {statistics.median(per_run):.1f} s (min {min(per_run):.1f}, max {max(per_run):.1f})"
        )
    local1, local2, ray2 = results[("local", 1)], results[("local", 2)], results[("ray", 2)]
    print(f"speed-up of 2 local workers over 1: {local1 / local2:.2f}x")
    start = ray_start_s()
    print(
        f"Ray: {ray2 - local2:+.1f} s over the local pool in all ({(ray2 - local2) / n:+.2f} s per run); "
        f"of that, starting a local Ray instance {start:.1f} s, so {(ray2 - local2 - start) / n:+.2f} s per run beyond it"
    )


if __name__ == "__main__":
    main()
