"""imitate: task-level imitation learning on a simulated humanoid (Muehlig et al., ICRA 2009).

Importing the package registers the Gymnasium environments ``imitate/Pouring-v0`` and
``imitate/Inserting-v0`` (``gym.make("imitate:imitate/Pouring-v0")`` imports it for you) and
sets nothing else: no environment variable, no matplotlib backend (see
:mod:`imitate.envs.rendering`). The Python API, each imported on first use (they load the
learner and the planner):

- :func:`load_run`: a run directory as typed objects (:class:`Run`: ``config``, ``model``,
  ``plan``, ``replay``, ``report``, ..., and ``replan(**settings)``).
- :func:`learn`: a :class:`~imitate.learning.LearnedModel` from task-space demonstrations.
- :func:`reproduce`: the robot's plan for a learned model in a scene.
- :func:`actions`: a plan's actions at the env's step, to play it in a task's env.
"""

from typing import TYPE_CHECKING

import gymnasium as gym

from imitate.envs import tasks
from imitate.errors import ImitateError

if TYPE_CHECKING:
    from imitate.learning import learn
    from imitate.motion.replay import actions, reproduce
    from imitate.run import Run, load_run

__all__ = ["ENV_ID", "ImitateError", "Run", "actions", "learn", "load_run", "reproduce"]
__version__ = "0.1.0"  # the package's version (pyproject.toml reads it)

ENV_ID = "imitate/Pouring-v0"  # the default task's

for _task in tasks.NAMES:  # one Gymnasium id per task
    _light = tasks.module(_task, "options")
    if _light.ENV_ID not in gym.registry:
        gym.register(id=_light.ENV_ID, entry_point=f"imitate.envs.{_task}.env:{_light.ENV_CLASS}",
                     max_episode_steps=500)

# The API's names and the modules they come from, imported when first asked for.
_LAZY = {
    "Run": "imitate.run", "load_run": "imitate.run", "learn": "imitate.learning",
    "reproduce": "imitate.motion.replay", "actions": "imitate.motion.replay",
}


def __getattr__(name: str):
    """The API's names of :data:`_LAZY`, imported when first asked for."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'imitate' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
