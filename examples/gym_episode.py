"""Drive RiverNav-v0 episodes: one with the bench's baseline LOS autopilot, one with random thruster commands.

    .venv/bin/python examples/gym_episode.py [--scenario harvard_beam_bridge] [--seed 0] [--frame frame.png]

Prints each episode's return, length and how it ended; with --frame, saves the last rendered frame.
"""

from __future__ import annotations

import argparse

import gymnasium
import numpy as np

import scenarios.gym


def episode(env, seed: int, policy) -> tuple[float, int, dict]:
    """Run one episode to its end; the return, the number of steps and the last info."""
    obs, info = env.reset(seed=seed)
    total, steps, done = 0.0, 0, False
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy(obs))
        total, steps, done = total + reward, steps + 1, terminated or truncated
    return total, steps, info


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scenario", default="harvard_beam_bridge")
    parser.add_argument(
        "--set",
        action="append",
        default=["stretch={start_m=1650.0, end_m=1710.0}"],
        help="scenario overrides (default: 60 m under the Harvard Bridge)",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--frame", help="save the last frame of the baseline episode to this PNG")
    args = parser.parse_args()

    env = gymnasium.make(scenarios.gym.ENV_ID, scenario=args.scenario, set=args.set, render_mode="rgb_array")
    baseline = episode(env, args.seed, lambda obs: env.unwrapped.baseline_action())
    if args.frame:
        import matplotlib.pyplot as plt

        plt.imsave(args.frame, env.render())
    rng = np.random.default_rng(args.seed)
    random = episode(env, args.seed, lambda obs: rng.uniform(-1.0, 1.0, 2).astype(np.float32))
    env.close()
    for name, (ret, steps, info) in (("baseline autopilot", baseline), ("random actions", random)):
        print(
            f"{name:>18}: return {ret:8.1f} over {steps} steps ({steps / 10:.1f} s), {info['outcome']}, "
            f"station {info['true_station_m']:.1f} m, |cross-track| {abs(info['true_cross_track_m']):.1f} m, "
            f"clearance {info['clearance_m']:.1f} m"
        )


if __name__ == "__main__":
    main()
