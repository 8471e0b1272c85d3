"""The Gymnasium environment: importing this package registers `riverbench/RiverNav-v0`.

import gymnasium, scenarios.gym
env = gymnasium.make("riverbench/RiverNav-v0", scenario="harvard_beam_bridge")
"""

from gymnasium.envs.registration import register, registry

from scenarios.gym.env import RewardConfig, RiverNavEnv

ENV_ID = "riverbench/RiverNav-v0"

if ENV_ID not in registry:
    register(id=ENV_ID, entry_point="scenarios.gym.env:RiverNavEnv")

__all__ = ["ENV_ID", "RewardConfig", "RiverNavEnv"]
