"""imitate: task-level imitation learning on a simulated humanoid (Muehlig et al., ICRA 2009).

Importing the package registers the Gymnasium environment ``imitate/Pouring-v0``
(``gym.make("imitate:imitate/Pouring-v0")`` imports it for you) and sets nothing else: no
environment variable, no matplotlib backend (see :mod:`imitate.envs.rendering`).
"""

import gymnasium as gym

from imitate.errors import ImitateError

__all__ = ["ENV_ID", "ImitateError"]
__version__ = "0.1.0"  # the package's version (pyproject.toml reads it)

ENV_ID = "imitate/Pouring-v0"

if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="imitate.envs.pouring:PouringEnv", max_episode_steps=500)
