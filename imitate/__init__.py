"""imitate: task-level imitation learning on a simulated humanoid (Muehlig et al., ICRA 2009).

Importing the package registers the Gymnasium environment ``imitate/Pouring-v0``
(``gym.make("imitate:imitate/Pouring-v0")`` imports it for you) and sets nothing else: no
environment variable, no matplotlib backend (see :mod:`imitate.envs.rendering`).
``imitate.load_run(path)`` reads a run directory as typed objects (:mod:`imitate.run`; imported
on first use, it loads the learner and the planner).
"""

from typing import TYPE_CHECKING

import gymnasium as gym

from imitate.errors import ImitateError

if TYPE_CHECKING:
    from imitate.run import Run, load_run

__all__ = ["ENV_ID", "ImitateError", "Run", "load_run"]
__version__ = "0.1.0"  # the package's version (pyproject.toml reads it)

ENV_ID = "imitate/Pouring-v0"

if ENV_ID not in gym.registry:
    gym.register(id=ENV_ID, entry_point="imitate.envs.pouring:PouringEnv", max_episode_steps=500)


def __getattr__(name: str):
    """``Run`` and ``load_run`` from :mod:`imitate.run`, imported when first asked for."""
    if name in ("Run", "load_run"):
        from imitate import run

        return getattr(run, name)
    raise AttributeError(f"module 'imitate' has no attribute {name!r}")
