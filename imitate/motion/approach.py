r"""The approach: the joint-space path from the robot's posture to the plan's start.

The replay moves the robot from where it stands, ``q_a``, to the plan's first posture ``q_b``
along

.. math:: q(s) = (1 - s)\, q_a + s\, q_b + \sin(\pi s)\, b, \qquad s \in [0, 1]

(timed by a cosine blend). The straight line (``b = 0``) is kept where it clears every pair by
the planner's margin plus its proximity zone; else the bend ``b`` ``(n,)`` [rad] minimises
``|b|^2 / 2 + w sum_s P(d_s - margin)`` over the samples ``s`` of the path, with ``P`` the
collision cost's potential, by L-BFGS on its analytic gradient ``b + w sum_s P'(d_s) sin(pi s)
dd_s/dq``. Joints the task does not drive keep ``b = 0``.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from imitate.motion.control import SAMPLE_STEP
from imitate.motion.costs import potential
from imitate.taskspace import TaskMap

__all__ = ["approach_clearance", "approach_cost", "approach_path", "bend_approach"]

_MIN_SAMPLES = 20  # samples along the approach, at least
_WEIGHT = 1e4  # w: the potential's weight against the bend's size [rad^2/m]


def _fractions(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """Fractions ``s`` in (0, 1) of the approach's samples: at most :data:`SAMPLE_STEP` apart
    in every joint along the straight line, at least :data:`_MIN_SAMPLES` of them."""
    k = max(_MIN_SAMPLES + 1, int(np.ceil(np.max(np.abs(qb - qa)) / SAMPLE_STEP)))
    return np.arange(1, k) / k


def approach_path(qa: np.ndarray, qb: np.ndarray, bend: np.ndarray, s: np.ndarray) -> np.ndarray:
    """Postures ``(len(s), n)`` of the approach from ``qa`` to ``qb`` ``(n,)`` bent by ``bend``
    ``(n,)`` [rad] at the fractions ``s``."""
    s = np.asarray(s, dtype=float)[:, None]
    return (1.0 - s) * qa + s * qb + np.sin(np.pi * s) * bend


def approach_clearance(
    task: TaskMap, qa: np.ndarray, qb: np.ndarray, bend: np.ndarray
) -> tuple[float, tuple[str, str] | None]:
    """Smallest signed distance [m] along the approach and its pair (``None`` if none is
    within 0.2 m)."""
    kin = task.kin
    best, pair = np.inf, None
    for q in approach_path(qa, qb, bend, _fractions(qa, qb)):
        kin.update(q)
        d, names = kin.min_distance()
        if d < best:
            best, pair = d, names
    return float(best), pair


def approach_cost(
    task: TaskMap, qa: np.ndarray, qb: np.ndarray, bend: np.ndarray, margin: float,
    epsilon: float,
) -> tuple[float, np.ndarray]:
    """The cost :func:`bend_approach` minimises (see the module) and its gradient ``(n,)``."""
    kin = task.kin
    s = _fractions(qa, qb)
    total, grad = 0.5 * float(bend @ bend), bend.copy()
    for q, shape in zip(approach_path(qa, qb, bend, s), np.sin(np.pi * s), strict=True):
        kin.update(q)
        near = kin.distances(margin + epsilon, jacobian=True)
        if len(near.dist):
            value, slope = potential(near.dist - margin, epsilon)
            total += _WEIGHT * float(value.sum())
            grad += _WEIGHT * shape * (slope @ near.jac)
    return total, grad * task.driven


def bend_approach(
    task: TaskMap, qa: np.ndarray, qb: np.ndarray, margin: float, epsilon: float
) -> np.ndarray:
    """The smallest bend ``(n,)`` [rad] (see the module) that keeps the approach from ``qa`` to
    ``qb`` ``margin`` [m] clear of everything where it can; zeros where the straight line
    already keeps ``margin + epsilon``."""
    zero = np.zeros(task.kin.n)
    if approach_cost(task, qa, qb, zero, margin, epsilon)[0] == 0.0:
        return zero
    result = minimize(
        lambda bend: approach_cost(task, qa, qb, bend, margin, epsilon), zero, jac=True,
        method="L-BFGS-B",
    )
    return result.x * task.driven
