"""Attractor optimization: find the attractor points whose rollout minimises the total cost.

:func:`plan_from_model` resamples the learned GMR mean and variance to the planning step, moves the
robot's start posture onto the learned start (by RMR), fits attractors evenly spaced in time (or the
paper's one per GMM component) to the GMR mean in least squares (:func:`setup`) and then minimises
``Phi(a) = sum_i w_i c_i`` by iRprop- (default; sign-based, robust to the collision cost's kinks) or
L-BFGS (scipy). If the attractors alone leave less than the margin to an obstacle (one under
the target, where the task fixes where the hands are relative to each other), it optimizes once
more with a null-space push per attractor added to the variables: the robot's redundancy, which
moves the body without changing the task. The plan's start, RMR's posture on the learned start,
is moved in the same null space away from the table and obstacles closer than the margin plus 3 cm.
The approach from the given posture to the plan's start is part of the movement: its clearance
counts in the plan's, and where its straight joint-space line would pass within the margin of
something it is bent (:mod:`.approach`). The minimizers are :mod:`.minimize`'s, the settings
:class:`~.plan_config.PlanConfig`. It returns a frozen :class:`Plan` with the best variables
found, whether or not the optimizer converged.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal, TypedDict, cast, overload

import numpy as np

from imitate.errors import ImitateError
from imitate.learning.tpgmm import FrameModel
from imitate.motion.approach import approach_clearance, bend_approach, clear_start
from imitate.motion.attractors import AttractorDynamics
from imitate.motion.control import (
    JointLimitCost,
    Rollout,
    backward,
    reach,
    rollout,
    segment_fractions,
)
from imitate.motion.costs import (
    Collision,
    JointAcceleration,
    JointLimits,
    PathLength,
    Similarity,
    weighting,
)
from imitate.motion.kinematics import Kinematics
from imitate.motion.minimize import lbfgs, rprop
from imitate.motion.plan import Plan
from imitate.motion.plan_config import PlanConfig
from imitate.motion.taskspace import TaskMap

if TYPE_CHECKING:
    from imitate.learning import LearnedModel

__all__ = ["Problem", "Setup", "plan_from_model", "setup"]

# Task position error [m] beyond the demonstrations' two standard deviations (largest over the
# steps and x, y, z) above which a plan's message says the target was not reached: deviating
# where the demonstrations varied is the planner's answer to obstacles, not a miss.
UNREACHED_ERROR = 0.05
# Width of an evenly spaced attractor's soft switch: the standard deviation of its Gaussian
# share, in spacings (a component's time spread is about as wide relative to the components'
# spacing).
_SWITCH_WIDTH = 0.4
# The null-space push's scale [1/rad] for iRprop-'s initial step, as the tolerance for the
# attractors: a push of 0.1 moves a joint by 0.5 % of its range per step (nullspace_gain 0.05).
_PUSH_SCALE = 0.1
# Ranges [m] of _min_distance's queries, the nearer first: a plan's closest pair is almost
# always within the first, and a pair's distance does not depend on the range it is asked in.
_MIN_DISTANCE_QUERIES = (0.05, 0.2)

# A cost term of :mod:`.costs`: ``term(rollout, target) -> (value, dc/dq, dc/dx)``.
CostTerm = Callable[[Rollout, np.ndarray], tuple[float, np.ndarray, np.ndarray]]


class Problem:
    """The total cost ``Phi(v)`` and its gradient for one start posture and learned model.

    The variables ``v`` are the attractors ``(K, m)``, or the attractors with each one's
    null-space push appended ``(K, m + n)``: the push of step ``t`` is ``blend_t @ v[:, m:]``.

    Args:
        task_map: Task map (with the kinematics).
        dynamics: Attractor dynamics.
        q_start: ``(n,)`` start posture.
        mean: ``(T + 1, m)`` GMR mean at the planning steps.
        weights: ``W_t`` at the planning steps, ``(T + 1, m)`` diagonals or ``(T + 1, m, m)``.
        config: The weights and parameters.
    """

    def __init__(
        self,
        task_map: TaskMap,
        dynamics: AttractorDynamics,
        q_start: np.ndarray,
        mean: np.ndarray,
        weights: np.ndarray,
        config: PlanConfig,
    ):
        kin = task_map.kin
        self.task_map, self.dynamics = task_map, dynamics
        self.q_start, self.config = q_start, config
        kin.update(q_start)
        self.x_start, _ = task_map(task_map.space.angle_ref(mean[0]))
        dt = config.dt
        self.limits = JointLimitCost(kin.lower, kin.upper, config.control.free_ratio)
        self.terms: dict[str, tuple[float, CostTerm]] = {
            "similarity": (config.similarity_weight, Similarity(mean, weights, dt)),
            "collision": (config.collision_weight, Collision(config.margin, config.epsilon, dt)),
            "joint_limits": (config.joint_limit_weight, JointLimits(self.limits, dt)),
            "path_length": (config.path_length_weight, PathLength(dt)),
            "joint_acceleration": (
                config.joint_acceleration_weight,
                JointAcceleration(config.max_joint_acceleration, dt),
            ),
        }
        self.n_evaluations = 0
        self.last: tuple[np.ndarray, Rollout] | None = None  # of the last evaluate

    def rollout(self, v: np.ndarray) -> tuple[np.ndarray, Rollout]:
        """Target trajectory ``(T + 1, m)`` and RMR rollout of the variables ``v``."""
        m = self.task_map.m
        target = self.dynamics.trajectory(v[:, :m], self.x_start)
        push = self.dynamics.blend @ v[:, m:] if v.shape[1] > m else None
        with_distances = self.config.collision_weight > 0
        distmax = cast(Collision, self.terms["collision"][1]).distmax if with_distances else 0.0
        self.n_evaluations += 1
        result = rollout(
            self.task_map, target, self.q_start, self.config.control, self.limits, distmax, push
        )
        return target, result

    @overload
    def evaluate(
        self, v: np.ndarray, terms: tuple[str, ...] | None = None, gradient: Literal[True] = True
    ) -> tuple[float, dict[str, float], np.ndarray]: ...

    @overload
    def evaluate(
        self, v: np.ndarray, terms: tuple[str, ...] | None = None, gradient: bool = True
    ) -> tuple[float, dict[str, float], np.ndarray | None]: ...

    def evaluate(
        self, v: np.ndarray, terms: tuple[str, ...] | None = None, gradient: bool = True
    ) -> tuple[float, dict[str, float], np.ndarray | None]:
        """``(Phi, {term: weighted value}, dPhi/dv (v's shape) or None)`` over ``terms``
        (all)."""
        target, result = self.rollout(v)
        self.last = target, result
        names = tuple(self.terms) if terms is None else terms
        values = {}
        gq = np.zeros_like(result.q)
        gx = np.zeros_like(target)
        for name in names:
            weight, term = self.terms[name]
            if weight == 0:
                values[name] = 0.0
                continue
            value, tq, tx = term(result, target)
            values[name] = weight * value
            gq += weight * tq
            gx += weight * tx
        total = float(sum(values.values()))
        if not gradient:
            return total, values, None
        m = self.task_map.m
        dpush = np.empty_like(result.nullspace_gradient) if v.shape[1] > m else None
        dx = backward(result, self.task_map, self.config.control, gq, gx, dpush)
        da = self.dynamics.gradient(dx)
        if dpush is None:
            return total, values, da
        return total, values, np.hstack([da, self.dynamics.blend.T @ dpush])


@dataclass(frozen=True)
class Setup:
    """The optimization of :func:`plan_from_model` before its first iteration.

    Attributes:
        times: ``(T + 1,)`` planning steps [s], ``dt`` apart from the first GMR time.
        mean, variance: ``(T + 1, m)`` GMR mean and variances resampled to ``times``.
        covariance: ``(T + 1, m, m)`` GMR covariance resampled to ``times``.
        weights: ``W_t`` of ``config.similarity``: ``(T + 1, m)`` diagonals, or ``(T + 1, m, m)``
            matrices (``precision``).
        problem: The total cost over the attractors, from the start posture ``problem.q_start``
            (reached from the given posture by RMR onto ``mean[0]``).
        a0: ``(K, m)`` attractors fitted to ``mean`` in weighted least squares.
    """

    times: np.ndarray
    mean: np.ndarray
    variance: np.ndarray
    covariance: np.ndarray
    weights: np.ndarray
    problem: Problem
    a0: np.ndarray


def setup(
    task_map: TaskMap,
    model: LearnedModel | FrameModel,
    *,
    q0: np.ndarray,
    config: PlanConfig = PlanConfig(),
    critical: Callable[[np.ndarray], np.ndarray] | None = None,
    importance: np.ndarray | None = None,
) -> Setup:
    """The problem :func:`plan_from_model` optimizes: resampled GMR, eq. 21 weights, attractor
    dynamics (attractors every ``attractor_spacing`` seconds, or one per GMM component with
    soft switching by the components' time spread and priors), the start posture, the
    least-squares attractors.

    Args:
        task_map: Task map of the robot (kinematics, objects, gaze).
        model: The learned model: GMR ``times`` ``(T_g,)`` [s] (increasing, from 0), ``mean``
            and ``covariance`` over ``m`` task dimensions, GMM over ``(t, x)``; or one learned in
            frames, reproduced at ``task_map``'s places (TP-GMM's product, in its space).
        q0: ``(n,)`` current posture [rad].
        config: Parameters.
        critical: The task's critical phase: the steps ``(T,) bool`` of a mean ``(T, m)``; the
            ``"oracle"`` and ``"importance"`` weightings need it.
        importance: ``(m, m)`` the task's measured importance in the critical phase (tolerance
            units, positive definite); the ``"importance"`` weighting needs it.

    Raises:
        ImitateError: On inconsistent shapes or non-finite inputs, or the oracle or importance
            weighting without what it reads.
    """
    if isinstance(model, FrameModel):
        model = model.at(task_map.origins(model.places))
    times, mean, variance = (
        np.asarray(v, dtype=float) for v in (model.times, model.mean, model.variance)
    )
    q0 = np.asarray(q0, dtype=float)
    kin = task_map.kin
    if (
        times.ndim != 1
        or len(times) < 2
        or mean.shape != (len(times), task_map.m)
        or variance.shape != mean.shape
        or q0.shape != (kin.n,)
    ):
        raise ImitateError(
            f"plan needs times (T,), mean and variance (T, {task_map.m}) with T >= 2 and q0 "
            f"({kin.n},); got {times.shape}, {mean.shape}, {variance.shape}, {q0.shape}"
        )
    if not all(np.all(np.isfinite(v)) for v in (times, mean, variance, q0)):
        raise ImitateError("plan inputs must be finite (no NaN or inf)")
    c = config
    n_steps = max(1, int(round((times[-1] - times[0]) / c.dt)))
    grid = times[0] + np.arange(n_steps + 1) * c.dt
    mu = np.column_stack([np.interp(grid, times, mean[:, i]) for i in range(task_map.m)])
    var = np.column_stack([np.interp(grid, times, variance[:, i]) for i in range(task_map.m)])
    tolerance = task_map.space.tolerance
    w_max = np.asarray(c.w_max if c.w_max is not None else 1.0 / np.square(tolerance))
    sigma_max = np.asarray(
        c.sigma_max if c.sigma_max is not None else c.sigma_max_scale * var.max(axis=0)
    )
    # element by element: a mean of covariances is one
    flat = np.asarray(model.covariance, dtype=float).reshape(len(times), -1)
    cov = np.column_stack([np.interp(grid, times, f) for f in flat.T])
    cov = cov.reshape(len(grid), task_map.m, task_map.m)
    steps = None  # the oracle's and importance's: the task's critical phase
    if c.similarity in ("oracle", "importance"):
        if critical is None:
            raise ImitateError(
                f"similarity={c.similarity!r} needs the task's critical phase (critical=)"
            )
        steps = critical(mu)
    weights = weighting(
        c.similarity, var, cov, w_max, np.maximum(sigma_max, 1e-12), steps, importance
    )

    duration = grid[-1] - grid[0]
    if c.attractor_spacing is None:  # the paper: one attractor per GMM component
        g = model.gmm
        centres = np.asarray(g.means_[:, 0], dtype=float).ravel() - times[0]
        widths, priors = np.sqrt(g.covariances_[:, 0, 0]), g.weights_
    else:
        k = max(2, round(duration / c.attractor_spacing))
        centres = (np.arange(k) + 0.5) * duration / k
        widths, priors = np.full(k, _SWITCH_WIDTH * duration / k), None
    interval = duration / len(centres)
    dynamics = AttractorDynamics(
        n_steps, c.dt, centres, c.omega_per_interval / interval, widths, priors
    )
    limits = JointLimitCost(kin.lower, kin.upper, c.control.free_ratio)
    q_start = reach(task_map, mu[0], q0, c.control, limits)
    if c.collision_weight > 0:
        q_start = clear_start(task_map, q_start, mu[0], c.control, limits, c.margin, var[0])
    problem = Problem(task_map, dynamics, q_start, mu, weights, c)
    a0 = dynamics.fit(mu, problem.x_start, weights)
    return Setup(grid, mu, var, cov, weights, problem, a0)


class _Best(TypedDict):
    """The best iterate of :func:`plan_from_model`'s minimizations."""

    v: np.ndarray
    cost: float
    rollout: tuple[np.ndarray, Rollout] | None  # the target and rollout of ``v``, if kept


def plan_from_model(
    task_map: TaskMap,
    model: LearnedModel | FrameModel,
    *,
    q0: np.ndarray,
    config: PlanConfig = PlanConfig(),
    critical: Callable[[np.ndarray], np.ndarray] | None = None,
    importance: np.ndarray | None = None,
) -> Plan:
    """Optimizes a whole-body movement that reproduces the learned task (paper section V).

    Args:
        task_map: Task map of the robot (kinematics, objects, gaze).
        model: The learned model (see :func:`setup`).
        q0: ``(n,)`` current posture [rad]; the plan starts where RMR brings it onto the GMR
            mean's start.
        config: Parameters.
        critical: The task's critical phase (:func:`setup`), for the oracle and importance
            weightings.
        importance: The task's measured importance (:func:`setup`), for the importance
            weighting.

    Returns:
        The :class:`Plan`; never raises for a colliding, unreachable or unconverged result, it
        says so in ``message``.

    Raises:
        ImitateError: On inconsistent shapes or non-finite inputs.
    """
    c = config
    start = setup(task_map, model, q0=q0, config=c, critical=critical, importance=importance)
    problem, a0, mu = start.problem, start.a0, start.mean

    history: list[tuple[float, dict[str, float]]] = []
    best: _Best = {"v": a0, "cost": np.inf, "rollout": None}

    def record(v, total, values):
        if np.isfinite(total) and total < best["cost"]:
            best.update(v=v.copy(), cost=total, rollout=problem.last)
        history.append((total, values))

    converged = _minimize(problem, a0, c, record)
    target, final = best["rollout"] or problem.rollout(best["v"])
    min_d, closest = _min_distance(task_map.kin, final.q)
    pushed = c.nullspace_push and c.collision_weight > 0 and min_d < c.margin
    alone = min_d
    if pushed:  # from the least-squares fit and from the best attractors, the better wins
        for a in (a0, best["v"]):
            v0 = np.hstack([a, np.zeros((len(a), task_map.kin.n))])
            converged = _minimize(problem, v0, c, record)
        target, final = best["rollout"] or problem.rollout(best["v"])
        min_d, closest = _min_distance(task_map.kin, final.q)

    q0 = np.asarray(q0, dtype=float)
    bend = np.zeros(task_map.kin.n)
    if c.collision_weight > 0:
        bend = bend_approach(task_map, q0, problem.q_start, c.margin, c.epsilon)
    approach_d, approach_pair = approach_clearance(task_map, q0, problem.q_start, bend)
    if approach_d < min_d:
        min_d, closest = approach_d, approach_pair

    v, m = best["v"], task_map.m
    push = v[:, m:] if v.shape[1] > m else np.zeros((len(v), task_map.kin.n))
    names = tuple(problem.terms) + ("total",)
    costs = {
        name: np.array([h[0] if name == "total" else h[1][name] for h in history]) for name in names
    }
    excess = np.abs(final.x - mu) - 2.0 * np.sqrt(start.variance)
    notes = ["converged" if converged else f"not converged in {c.max_iter} iterations (best plan)"]
    if pushed:
        notes.append(f"null-space push: the attractors alone kept {alone * 1000:.1f} mm")
    if np.any(bend):
        notes.append(f"approach bent by up to {np.degrees(np.abs(bend).max()):.1f} deg")
    if min_d < 0:
        notes.append(f"collision: {closest} at {min_d * 1000:.1f} mm")
    worst = float(np.max(excess[:, task_map.space.position_columns]))
    if worst > UNREACHED_ERROR:
        notes.append(
            f"target not reached: task position error up to {worst:.3f} m beyond the "
            f"demonstrations' 2 sigma"
        )
    if final.clipped:
        notes.append(f"joint angles clipped at {final.clipped} steps")
    return Plan(
        times=start.times, attractors=v[:, :m], push=push, target=target, x=final.x, q=final.q,
        q_start=problem.q_start, approach_bend=bend, mean=mu, variance=start.variance,
        covariance=start.covariance,
        weights=np.diagonal(start.weights, axis1=1, axis2=2).copy()
        if start.weights.ndim == 3 else start.weights,
        costs=costs, min_distance=min_d, closest=closest, converged=converged,
        clipped=final.clipped, message="; ".join(notes), n_iter=max(len(history) - 1, 0),
        n_evaluations=problem.n_evaluations,
    )


def _minimize(problem: Problem, v0: np.ndarray, c: PlanConfig, record) -> bool:
    """Minimizes ``problem`` from ``v0`` by ``c.optimizer``, each iterate passed to ``record``;
    iRprop-'s first steps scaled per variable (``c.rprop_step`` times the similarity tolerance of
    an attractor's dimension, :data:`_PUSH_SCALE` for a null-space push). Returns whether it
    converged."""
    if c.optimizer == "lbfgs":
        return lbfgs(problem.evaluate, v0, max_iter=c.max_iter, tol=c.tol, record=record)
    m = problem.task_map.m
    tolerance = problem.task_map.space.tolerance
    scale = np.concatenate([tolerance, np.full(v0.shape[1] - m, _PUSH_SCALE)])
    step = c.rprop_step * np.broadcast_to(scale, v0.shape)
    return rprop(
        problem.evaluate, v0, step, max_iter=c.max_iter, tol=c.tol, patience=c.patience,
        record=record,
    )


def _min_distance(kin: Kinematics, q: np.ndarray) -> tuple[float, tuple[str, str] | None]:
    """Smallest distance and its pair over the steps ``q`` ``(T + 1, n)`` and the samples
    along the straight lines between them (the path the robot takes); ``(0.2, None)`` if
    nothing comes closer than 0.2 m."""
    along = [
        (1.0 - s) * qa + s * qb
        for qa, qb in zip(q[:-1], q[1:], strict=True)
        for s in segment_fractions(qa, qb)
    ]
    for distmax in _MIN_DISTANCE_QUERIES:  # the nearer first: fewer pairs to measure
        best, pair = distmax, None
        for qt in (*q, *along):
            kin.update(qt)
            d, names = kin.min_distance(distmax)
            if d < best:
                best, pair = d, names
        if pair is not None:
            break
    return float(best), pair
