"""RiverNav-v0 environment steps per second, LiDAR observation on: one process, and two in gymnasium's AsyncVectorEnv.

Each step is one LiDAR revolution of simulation (ray cast, the receiver at 5 Hz, the matchers and
estimators of the scenario) with the baseline autopilot's commands. Prints the median of --rounds
rounds of --steps steps (after a reset and a warm-up step) and the two-process speed-up.

    .venv/bin/python benchmarks/gym_env.py [--scenario harvard_beam_bridge] [--steps 100] [--rounds 3]
"""

from __future__ import annotations

import argparse
import statistics
import time

import gymnasium
import numpy as np

import scenarios.gym


def make(scenario: str, sets: list[str]):
    return lambda: gymnasium.make(scenarios.gym.ENV_ID, scenario=scenario, set=sets)


def single(scenario: str, sets: list[str], steps: int, seed: int) -> float:
    env = make(scenario, sets)()
    env.reset(seed=seed)
    env.step(env.unwrapped.baseline_action())
    start = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(env.unwrapped.baseline_action())
        if terminated or truncated:
            env.reset(seed=seed)
    rate = steps / (time.perf_counter() - start)
    env.close()
    return rate


def vector(scenario: str, sets: list[str], steps: int, seed: int, n: int) -> float:
    envs = gymnasium.vector.AsyncVectorEnv([make(scenario, sets) for _ in range(n)])
    envs.reset(seed=[seed + i for i in range(n)])
    cruise = np.full((n, 2), 0.78, np.float32)
    envs.step(cruise)
    start = time.perf_counter()
    for _ in range(steps):
        envs.step(cruise)  # autoreset handles episode ends
    rate = n * steps / (time.perf_counter() - start)
    envs.close()
    return rate


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", default="harvard_beam_bridge")
    parser.add_argument("--set", action="append", default=[])
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--rounds", type=int, default=3)
    args = parser.parse_args()
    one = [single(args.scenario, args.set, args.steps, r) for r in range(args.rounds)]
    two = [vector(args.scenario, args.set, args.steps, r, 2) for r in range(args.rounds)]
    print(f"scenario {args.scenario}: {args.steps} steps x {args.rounds} rounds, LiDAR range image on, every matcher and estimator of the scenario")
    print(f"  1 process : {statistics.median(one):6.1f} steps/s  (rounds: {', '.join(f'{r:.1f}' for r in one)})")
    print(f"  2 processes (AsyncVectorEnv): {statistics.median(two):6.1f} steps/s in total  (rounds: {', '.join(f'{r:.1f}' for r in two)})")
    print(f"  speed-up: {statistics.median(two) / statistics.median(one):.2f}x")


if __name__ == "__main__":
    main()
