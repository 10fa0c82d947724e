"""imitate: task-level imitation learning on a simulated humanoid (Muehlig et al., ICRA 2009).

Importing the package registers the Gymnasium environment ``imitate/Pouring-v0``
(``gym.make("imitate:imitate/Pouring-v0")`` imports it for you) and selects the headless OpenGL
backend before MuJoCo is first imported.
"""

import gymnasium as gym

from imitate.envs import rendering  # noqa: F401  (sets MUJOCO_GL before anything imports mujoco)
from imitate.errors import ImitateError

__all__ = ["ENV_ID", "ImitateError"]
__version__ = "0.1.0"

ENV_ID = "imitate/Pouring-v0"

if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="imitate.envs.pouring:PouringEnv", max_episode_steps=500)
