r"""Motion generation (paper section V): attractor-based whole-body movement optimization.

Notation (the paper's; each formula is stated and derived in the docstring of the module
that implements it):

==============  =================================================================================
``T``           number of planning steps; trajectories have ``T + 1`` samples, step ``dt`` [s]
``m``           task dimensions (7 for eq. 1); ``n`` planned joints (18, head columns zero)
``K``           attractors (every 0.15 s, or one per GMM component); ``a`` ``(K, m)`` points
``c_t``         null-space push ``(n,)`` [1/rad] (:mod:`.control`), ``(K, n)`` per attractor
``x_t``         target (attractor) trajectory ``x = S_x s_0 + Psi a`` (:mod:`.attractors`)
``phi(q)``      task map (:class:`imitate.motion.taskspace.TaskMap`); ``J`` its Jacobian ``(m, n)``
``J#``          weighted damped pseudo-inverse of ``J``
``q_t``         joint angles from resolved motion rate control (:mod:`.control`)
``mu_t``        GMR mean; ``sigma_t`` GMR variance; ``W_t`` similarity weights (:mod:`.costs`)
``Phi``         total cost ``sum_i w_i c_i``; its gradient by the adjoint recursion
==============  =================================================================================

:func:`plan_from_model` is the entry point; it returns a frozen :class:`Plan`
(:mod:`.plan`, which also stores it); :mod:`.metrics` measures it.
"""

from imitate.motion.attractors import AttractorDynamics
from imitate.motion.control import ControlConfig, JointLimitCost, Rollout, reach, rollout
from imitate.motion.costs import (
    SIMILARITIES,
    Collision,
    JointAcceleration,
    JointLimits,
    PathLength,
    Similarity,
    similarity_weights,
    weighting,
)
from imitate.motion.optimizer import Problem, Setup, plan_from_model, setup
from imitate.motion.plan import Plan
from imitate.motion.plan_config import OPTIMIZERS, PlanConfig

__all__ = [
    "OPTIMIZERS",
    "SIMILARITIES",
    "AttractorDynamics",
    "Collision",
    "ControlConfig",
    "JointAcceleration",
    "JointLimitCost",
    "JointLimits",
    "PathLength",
    "Plan",
    "PlanConfig",
    "Problem",
    "Rollout",
    "Setup",
    "Similarity",
    "plan_from_model",
    "reach",
    "rollout",
    "setup",
    "similarity_weights",
    "weighting",
]
