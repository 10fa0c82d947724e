"""imitate: task-level imitation learning on a simulated humanoid (Muehlig et al., ICRA 2009).

Importing the package selects the headless OpenGL backend before MuJoCo is first imported.
"""

from imitate import rendering  # noqa: F401  (sets MUJOCO_GL before anything imports mujoco)
from imitate.errors import ImitateError

__all__ = ["ImitateError"]
__version__ = "0.1.0"
