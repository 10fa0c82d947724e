"""Gymnasium environments of the pouring task; importing registers ``imitate/Pouring-v0``."""

import gymnasium as gym

import imitate  # noqa: F401  (selects the headless GL backend before MuJoCo is imported)

ENV_ID = "imitate/Pouring-v0"

if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="envs.pouring:PouringEnv", max_episode_steps=500)

__all__ = ["ENV_ID"]
