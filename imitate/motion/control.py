r"""Whole-body resolved motion rate control (RMR): task trajectory -> joint trajectory.

Per step ``t`` (``n`` joints, ``m`` task dimensions):

.. math::
    J^\# = W^{-1} J^T (J W^{-1} J^T + \lambda I)^{-1}, \qquad
    q_{t+1} = q_t + J^\# (x_{t+1} - \phi(q_t)) - \alpha (I - J^\# J) W^{-1} (\nabla H(q_t) - c_t)

with the joint metric ``W^{-1} = diag(range_i)`` (zero for joints the task must not drive, the
head), the joint-limit "border" cost ``H`` (zero in a free zone around each range's centre,
quadratic outside it) and an optional null-space push ``c_t`` [1/rad] (zero by default): the
null-space step descends ``H(q) - c_t . q``, moving the body without changing the task. ``q`` is
clipped to the joint ranges, and each clip is counted.

The task map ``phi`` and its Jacobian are the task's space on the held objects (eq. 1 unless it
declares another), :class:`imitate.motion.taskspace.TaskMap`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from imitate.errors import ImitateError
from imitate.motion import _planner
from imitate.motion.kinematics import Distances, Kinematics
from imitate.motion.taskspace import TaskFrame, TaskMap

__all__ = [
    "SAMPLE_STEP",
    "ControlConfig",
    "JointLimitCost",
    "Rollout",
    "backward",
    "reach",
    "rollout",
    "segment_fractions",
]

# Largest joint step [rad] between two distance samples along a step. The robot moves along the
# straight line in joint space between steps (the replay interpolates so), and on a long step the
# distance can dip far below its value at the ends and the midpoint.
SAMPLE_STEP = 0.05


def segment_fractions(qa: np.ndarray, qb: np.ndarray) -> np.ndarray:
    """Fractions ``s`` in (0, 1) of the samples ``(1 - s) qa + s qb`` along a step from ``qa``
    to ``qb`` ``(n,)``: the midpoint, or equal sub-steps of at most :data:`SAMPLE_STEP` in
    every joint."""
    k = _sub_steps(float(np.max(np.abs(qb - qa))))
    return np.arange(1, k) / k


def _sub_steps(largest: float) -> int:
    """Number of sub-steps of a step whose largest joint change is ``largest`` [rad]."""
    return max(2, math.ceil(largest / SAMPLE_STEP))


@dataclass(frozen=True)
class ControlConfig:
    """Parameters of the RMR rollout.

    Attributes:
        damping: ``lambda`` added to ``J W^-1 J^T`` [task units^2 rad]; keeps ``J^#`` bounded
            near singularities.
        nullspace_gain: ``alpha``, fraction of the joint-limit gradient step taken per step.
        free_ratio: Fraction of each half range around the centre where ``H`` is zero.
        fixed_joints: Joints the task does not drive (kept at their start angle).
    """

    damping: float = 1e-4
    nullspace_gain: float = 0.05
    free_ratio: float = 0.7
    fixed_joints: tuple[str, ...] = ("head_pan", "head_tilt")

    def __post_init__(self):
        if not self.damping > 0 or not self.nullspace_gain >= 0 or not 0 <= self.free_ratio < 1:
            raise ImitateError(
                f"ControlConfig needs damping > 0, nullspace_gain >= 0, 0 <= free_ratio < 1; got "
                f"{self.damping}, {self.nullspace_gain}, {self.free_ratio}"
            )


class JointLimitCost:
    r"""Border joint-limit cost ``H(q) = 1/2 sum_i ((q_i - b_i) / p_i)^2`` outside the free zone.

    ``b_i`` is the free zone's border on the side ``q_i`` is on, ``p_i`` the penalty range
    between the border and the limit. Its Hessian is diagonal.
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray, free_ratio: float):
        centre, half = 0.5 * (lower + upper), 0.5 * (upper - lower)
        self.low_border, self.high_border = centre - free_ratio * half, centre + free_ratio * half
        self.scale = 1.0 / ((1.0 - free_ratio) * half) ** 2

    def __call__(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(H (...,), dH/dq (..., n), diag d2H/dq2 (..., n))`` for ``q`` of shape ``(..., n)``."""
        excess = np.minimum(q - self.low_border, 0.0) + np.maximum(q - self.high_border, 0.0)
        grad = self.scale * excess
        return 0.5 * np.sum(grad * excess, axis=-1), grad, self.scale * (excess != 0.0)


@dataclass(frozen=True)
class Rollout:
    """One RMR rollout of a task trajectory.

    Attributes:
        q: ``(T + 1, n)`` joint angles [rad].
        x: ``(T + 1, m)`` task state reached, ``phi(q_t)``.
        jac: ``(T, m, n)`` task Jacobians at ``q_0 .. q_{T-1}``.
        pinv: ``(T, n, m)`` their weighted damped pseudo-inverses ``J^#``.
        nullspace_gradient: ``(T, n)`` ``g_t = dH/dq - c_t`` at ``q_0 .. q_{T-1}``, what the
            null-space step descends.
        limit_hessian: ``(T, n)`` diagonal Hessians of ``H`` at ``q_0 .. q_{T-1}``.
        solved: ``(T, m)`` ``(J W^-1 J^T + lambda I)^-1 (x_{t+1} - phi(q_t) + alpha J W^-1
            g_t)``: the step is ``W^-1 J^T solved - alpha W^-1 g_t``.
        clipped_at: ``(T, n)`` the joints clipped to their ranges in ``q_1 .. q_T``.
        frames: ``T`` :class:`TaskFrame` at ``q_0 .. q_{T-1}``.
        distances: ``T + 1`` :class:`Distances` (with gradients) of the pairs closer than the
            rollout's ``distmax``; empty if it was 0.
        between: ``(t, s, Distances)`` at the postures ``(1 - s) q_t + s q_{t+1}`` along each
            step, ``s`` from :func:`segment_fractions`: the robot moves between the steps along
            the straight line in joint space (the replay interpolates so), where it can come
            closer than at either step; empty if ``distmax`` was 0.
    """

    q: np.ndarray
    x: np.ndarray
    jac: np.ndarray
    pinv: np.ndarray
    nullspace_gradient: np.ndarray
    limit_hessian: np.ndarray
    solved: np.ndarray
    clipped_at: np.ndarray
    frames: tuple[TaskFrame, ...]
    distances: tuple[Distances, ...]
    between: tuple[tuple[int, float, Distances], ...]

    @property
    def clipped(self) -> int:
        """Number of steps with a joint angle clipped to its range."""
        return int(np.count_nonzero(np.any(self.clipped_at, axis=1)))


def _metric(kin: Kinematics, task_map: TaskMap) -> np.ndarray:
    """The joint metric: each driven joint's full range (not its narrowed one) [rad]."""
    return kin.span * task_map.driven


def rollout(
    task_map: TaskMap,
    target: np.ndarray,
    q0: np.ndarray,
    config: ControlConfig,
    limits: JointLimitCost,
    distmax: float = 0.0,
    push: np.ndarray | None = None,
) -> Rollout:
    """Tracks ``target`` ``(T + 1, m)`` (``target[0]`` unused) by RMR from ``q0`` ``(n,)``.

    Args:
        task_map: The task map ``phi`` and its Jacobian, on the robot's kinematics.
        target: ``(T + 1, m)`` task states to track; ``target[0]`` is unused.
        q0: ``(n,)`` start joint angles [rad].
        config: Damping and null-space gain of the steps.
        limits: Joint-limit cost ``H`` the null-space step descends.
        distmax: Compute the signed distances (and their gradients) of pairs closer than this
            [m] at every step and midway between steps; 0 for none.
        push: ``(T, n)`` null-space push ``c_t`` [1/rad] of the steps; ``None`` for none.
    """
    kin = task_map.kin
    T = len(target) - 1
    n, m = kin.n, target.shape[1]
    winv = _metric(kin, task_map)
    q = np.empty((T + 1, n))
    x = np.empty((T + 1, m))
    jac = np.empty((T, m, n))
    pinv = np.empty((T, n, m))
    solved = np.empty((T, m))
    nullspace_gradient = np.empty((T, n))
    push = np.zeros((T, n)) if push is None else np.ascontiguousarray(push, dtype=float)
    unclipped = np.empty((T, n))
    frames, distances, between = [], [], []
    q[0] = q0
    target = np.ascontiguousarray(target, dtype=float)
    angle_ref = task_map.space.angle_ref(target)
    step = _planner._rmr_step
    for t in range(T + 1):
        kin.update(q[t])
        x[t], J, frame = task_map.evaluate(angle_ref[t])
        if distmax > 0:
            distances.append(kin.distances(distmax, jacobian=True))
        if t == T:
            break
        largest = step(
            t, J, x, target, q, winv, config.damping, config.nullspace_gain, limits.low_border,
            limits.high_border, limits.scale, push, kin.lower, kin.upper, jac, pinv, solved,
            nullspace_gradient, unclipped,
        )
        frames.append(frame)
        if distmax > 0:  # at segment_fractions(q[t], q[t + 1])
            k = _sub_steps(largest)
            for i in range(1, k):
                s = i / k
                kin.update_between(q[t], q[t + 1], s)
                between.append((t, s, kin.distances(distmax, jacobian=True)))
    return Rollout(
        q, x, jac, pinv, nullspace_gradient, limits(q[:T])[2], solved, q[1:] != unclipped,
        tuple(frames), tuple(distances), tuple(between),
    )


def backward(
    result: Rollout,
    task_map: TaskMap,
    config: ControlConfig,
    gq: np.ndarray,
    gx: np.ndarray,
    push_gradient: np.ndarray | None = None,
) -> np.ndarray:
    r"""Total derivative w.r.t. the target trajectory (and the null-space push) by the adjoint
    recursion.

    ``lambda_T = gq_T``; ``lambda_t = gq_t + lambda_{t+1} dq_{t+1}/dq_t`` and
    ``dPhi/dx_{t+1} = gx_{t+1} + lambda_{t+1} J^#_t``, with

    .. math::
        \lambda \frac{\partial q_{t+1}}{\partial q_t} = \lambda (I - J^\# J)
        (I - \alpha W^{-1} H'') + u^T D_{\ell - z} J - p^T D_{y - \alpha g} J

    where ``u = M^-1 e``, ``p = (lambda J^#)^T``, ``l = W^-1 lambda^T``, ``y = J^# e``,
    ``z = W^-1 J^T p``, ``g = W^-1 (dH/dq - c_t)``, ``M = J W^-1 J^T + lambda I`` and ``e =
    x_{t+1} - phi(q_t) + alpha J g`` (the null-space step is ``alpha (J^# J g - g)``): the
    ``D`` terms are
    ``lambda (dJ^#/dq) e + alpha p^T (dJ/dq) g``, using the symmetry of second derivatives,
    ``a^T (dJ/dq_i) b = [a^T D_b J]_i``, with ``D_b J`` the derivative of ``J`` along ``b``
    (:meth:`TaskMap.rates`, exact). A joint clipped to its range in ``q_{t+1}`` passes nothing
    back (its row of ``dq_{t+1}/dq_t`` and ``J^#_t`` is zero). The push's derivative is
    ``dPhi/dc_t = alpha lambda_{t+1} (I - J^# J) W^-1``. Exact: no term is neglected.

    Args:
        result: The rollout to differentiate (:func:`rollout`).
        task_map: The task map the rollout used; its kinematics are updated here.
        config: The control parameters the rollout used.
        gq: ``(T + 1, n)`` explicit gradients of the cost w.r.t. ``q_t``.
        gx: ``(T + 1, m)`` explicit gradients w.r.t. the target ``x_t``.
        push_gradient: ``(T, n)``, written with ``dPhi/dc_t`` if given.

    Returns:
        ``(T + 1, m)`` gradient w.r.t. the target trajectory (row 0 is ``gx[0]``).
    """
    T = len(result.jac)
    kin = task_map.kin
    winv = _metric(kin, task_map)
    alpha = config.nullspace_gain
    dx = gx.copy()
    lam = gq[T].copy()
    m = result.jac.shape[1]
    p, ln, b, d = np.empty(m), np.empty(kin.n), np.empty(kin.n), np.empty(kin.n)
    directions, update = _planner._adjoint_directions, _planner._adjoint_update
    nullspace_steps = alpha * winv * result.nullspace_gradient
    for t in range(T - 1, -1, -1):
        directions(t, lam, result.clipped_at, result.pinv, result.jac, result.solved, winv,
                   nullspace_steps, p, ln, b, d, dx)
        if push_gradient is not None:
            push_gradient[t] = alpha * b
        kin.update(result.q[t], held=False)
        curvature = task_map.curvature(result.solved[t], b, -p, d, result.frames[t])
        update(t, gq, ln, alpha, winv, result.limit_hessian, curvature, lam)
    return dx


def reach(
    task_map: TaskMap,
    goal: np.ndarray,
    q0: np.ndarray,
    config: ControlConfig,
    limits: JointLimitCost,
    steps: int = 200,
    rate: float = 0.2,
) -> np.ndarray:
    """Joint angles ``(n,)`` whose task state approaches ``goal`` ``(m,)``, by ``steps`` RMR
    steps from ``q0`` that each close ``rate`` of the remaining task error."""
    kin = task_map.kin
    target = np.empty((steps + 1, len(goal)))
    kin.update(q0)
    x0, _ = task_map(task_map.space.angle_ref(goal))
    remaining = (1.0 - rate) ** np.arange(steps + 1)
    target[:] = goal + remaining[:, None] * (x0 - goal)
    return rollout(task_map, target, q0, config, limits).q[-1]
