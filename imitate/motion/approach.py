r"""The approach: the joint-space path from the robot's posture to the plan's start, and where
that start is.

The start is reached by RMR onto the learned start (:func:`~imitate.motion.control.reach`), which
knows nothing of the scene: an obstacle next to where the demonstrations began can be within
reach of a hand there, and no attractor moves the start. :func:`clear_start` moves it in the
task's null space (the task state stays the learned start; in a space of the objects' relation
the hands can move together) until it keeps the margin plus :data:`START_ZONE` to every geom
fixed in the world (the table, obstacles), where the null space allows. Where it does not (a
space relative to a place pins the objects) and the start still lies within the margin, the
task state moves too, in the positions and as far as the demonstrations spread at their start:
each step along the potential's descent in the task space scaled by their variances.

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

from imitate.errors import ImitateError
from imitate.motion.control import SAMPLE_STEP, ControlConfig, JointLimitCost, rollout
from imitate.motion.costs import potential
from imitate.motion.taskspace import TaskMap

__all__ = [
    "START_ZONE", "approach_clearance", "approach_cost", "approach_path", "bend_approach",
    "clear_start",
]

_MIN_SAMPLES = 20  # samples along the approach, at least
_WEIGHT = 1e4  # w: the potential's weight against the bend's size [rad^2/m]
# Clearance [m] beyond the margin that the start keeps to the fixed geoms where it can: a hand
# leaving the start moves up to a few centimetres in the first step.
START_ZONE = 0.03
_START_GAIN = 2.0  # g [1/m]: the push [1/rad] per unit of the potential's gradient [m/rad]
_START_STEPS = 300  # RMR steps of clear_start, at most
_GOAL_STEP = 0.002  # [m]: how far a step of clear_start moves the task state, where it does


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
    task_map: TaskMap, qa: np.ndarray, qb: np.ndarray, bend: np.ndarray
) -> tuple[float, tuple[str, str] | None]:
    """Smallest signed distance [m] along the approach and its pair (``None`` if none is
    within 0.2 m)."""
    kin = task_map.kin
    best, pair = np.inf, None
    for q in approach_path(qa, qb, bend, _fractions(qa, qb)):
        kin.update(q)
        d, names = kin.min_distance()
        if d < best:
            best, pair = d, names
    return float(best), pair


def approach_cost(
    task_map: TaskMap, qa: np.ndarray, qb: np.ndarray, bend: np.ndarray, margin: float,
    epsilon: float,
) -> tuple[float, np.ndarray]:
    """The cost :func:`bend_approach` minimises (see the module) and its gradient ``(n,)``."""
    kin = task_map.kin
    s = _fractions(qa, qb)
    total, grad = 0.5 * float(bend @ bend), bend.copy()
    for q, shape in zip(approach_path(qa, qb, bend, s), np.sin(np.pi * s), strict=True):
        kin.update(q)
        near = kin.distances(margin + epsilon, jacobian=True)
        if len(near.dist):
            value, slope = potential(near.dist - margin, epsilon)
            total += _WEIGHT * float(value.sum())
            grad += _WEIGHT * shape * (slope @ near.jac)
    return total, grad * task_map.driven


def bend_approach(
    task_map: TaskMap, qa: np.ndarray, qb: np.ndarray, margin: float, epsilon: float
) -> np.ndarray:
    """The smallest bend ``(n,)`` [rad] (see the module) that keeps the approach from ``qa`` to
    ``qb`` ``margin`` [m] clear of everything where it can; zeros where the straight line
    already keeps ``margin + epsilon``."""
    zero = np.zeros(task_map.kin.n)
    if approach_cost(task_map, qa, qb, zero, margin, epsilon)[0] == 0.0:
        return zero
    result = minimize(
        lambda bend: approach_cost(task_map, qa, qb, bend, margin, epsilon), zero, jac=True,
        method="L-BFGS-B",
    )
    return result.x * task_map.driven


def clear_start(
    task_map: TaskMap, q: np.ndarray, goal: np.ndarray, config: ControlConfig,
    limits: JointLimitCost, margin: float, spread: np.ndarray | None = None,
) -> np.ndarray:
    """The start posture ``q`` ``(n,)`` [rad] moved clear of the fixed geoms (see the module):
    RMR steps onto the task state ``goal`` ``(m,)`` with the null-space push ``-g dP/dq``, ``P``
    the collision cost's potential over the pairs with a fixed geom closer than ``margin +
    START_ZONE`` [m]; at most ``_START_STEPS`` of them. ``q`` itself where none is closer. If
    the start is still within ``margin`` of a fixed geom and ``spread`` ``(m,)`` (the
    demonstrations' variances at the start) is given, as many steps again that also move the
    task state, in its position columns, by ``_GOAL_STEP`` along ``-spread * dP/dx``."""
    kin = task_map.kin
    if kin.pairs is None:
        raise ImitateError("clear_start needs the Kinematics to be built with geoms")
    fixed = kin.pairs.fixed(kin.model)
    q, closest = _clear(task_map, q, goal, config, limits, margin, fixed, None)
    if spread is not None and closest < margin:
        moving = np.zeros_like(spread)
        columns = task_map.space.position_columns
        moving[columns] = spread[columns]
        q, _ = _clear(task_map, q, goal, config, limits, margin, fixed, moving)
    return q


def _clear(
    task_map: TaskMap, q: np.ndarray, goal: np.ndarray, config: ControlConfig,
    limits: JointLimitCost, margin: float, fixed: np.ndarray, spread: np.ndarray | None,
) -> tuple[np.ndarray, float]:
    """:func:`clear_start`'s steps (the task state moving by ``spread`` where given); the start
    and its distance [m] to the closest fixed geom (``inf`` beyond the zone)."""
    kin = task_map.kin
    for _ in range(_START_STEPS):
        kin.update(q)
        near = kin.distances(margin + START_ZONE, jacobian=True)
        keep = fixed[near.pairs]
        if not np.any(keep):
            return q, np.inf
        _, slope = potential(near.dist[keep] - margin, START_ZONE)
        gradient = slope @ near.jac[keep]  # dP/dq
        if spread is not None:  # dP/dx, least squares through J^T
            _, J = task_map(task_map.space.angle_ref(goal))
            step = spread * np.linalg.lstsq(J.T, gradient, rcond=None)[0]
            goal = goal - _GOAL_STEP * step / max(float(task_map.space.distance(step)), 1e-12)
        q = rollout(task_map, np.tile(goal, (2, 1)), q, config, limits,
                    push=-_START_GAIN * gradient[None]).q[-1]
    kin.update(q)
    near = kin.distances(margin + START_ZONE)
    keep = fixed[near.pairs]
    return q, float(near.dist[keep].min()) if np.any(keep) else np.inf
