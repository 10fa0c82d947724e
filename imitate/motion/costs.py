r"""Cost terms of the movement optimization, each with its explicit analytic gradient.

Every term maps a rollout (``q_{0:T}``, distances) and the target trajectory ``x_{0:T}`` to a
value and its explicit gradients ``(gq (T+1, n), gx (T+1, m))``; per-step costs are integrated
over time (multiplied by ``dt``) so they do not depend on the step. The chain through the
rollout is :func:`imitate.motion.control.backward`.

- :class:`Similarity`: eqs. 20-22, ``c = sum_t (x_t - mu_t)^T W_t (x_t - mu_t) dt`` with
  ``W_t`` from the GMR variances by eq. 21's ramp, or by one of the alternatives it is compared
  with (:data:`SIMILARITIES`, :func:`weighting`).
- :class:`Collision`: CHOMP's potential of ``d - margin`` for every pair closer than
  ``margin + epsilon``: ``(d' - eps)^2 / (2 eps)`` for ``0 <= d' < eps``, ``eps/2 - d'`` below 0,
  at every step and along each step (:func:`imitate.motion.control.segment_fractions`; the
  samples along a step standing together for as much as one at a step).
- :class:`JointLimits`: the border cost ``H`` of :class:`imitate.motion.control.JointLimitCost`.
- :class:`PathLength`: the joint-space trajectory length as ``sum_t |q_{t+1} - q_t|^2 / dt``
  (squared so it is differentiable at rest).
- :class:`JointAcceleration`: joint accelerations above ``a_max``, squared, from rest to rest;
  zero for a movement within it.
"""

from __future__ import annotations

import numpy as np

from imitate import defaults
from imitate.errors import ImitateError
from imitate.motion.control import JointLimitCost, Rollout
from imitate.motion.kinematics import Distances

__all__ = [
    "REGULARIZATION",
    "SIMILARITIES",
    "Collision",
    "JointAcceleration",
    "JointLimits",
    "PathLength",
    "Similarity",
    "regularized_precision",
    "similarity_weights",
    "weighting",
]

# How W_t is made from the learned model (:func:`weighting`): eq. 21, the default, and the
# alternatives the paper's claim is tested against.
SIMILARITIES = defaults.SIMILARITIES
# lambda of the precision weightings' floor ``Sigma_t + lambda diag(tolerance^2)``: 1 makes a
# dimension at zero variance as stiff, relative to the others, as eq. 21's ``w_max``; it also
# keeps the inverse of a covariance of 5 demonstrations in 7 dimensions (rank 4 at most) finite.
REGULARIZATION = 1.0


def similarity_weights(variance: np.ndarray, w_max: np.ndarray, sigma_max: np.ndarray):
    """Eq. 21: ``w = w_max (1 - sigma / sigma_max)`` below ``sigma_max``, else 0.

    Args:
        variance: GMR variances ``sigma_hat`` ``(T, m)``.
        w_max: ``(m,)`` weights at zero variance.
        sigma_max: ``(m,)`` variances where the weight reaches zero.

    Returns:
        ``(T, m)`` diagonals of ``W_t``.
    """
    w_max, sigma_max = np.asarray(w_max, float), np.asarray(sigma_max, float)
    if np.any(w_max < 0) or np.any(~(sigma_max > 0)):
        raise ImitateError(f"w_max must be >= 0 and sigma_max > 0; got {w_max}, {sigma_max}")
    return w_max * np.clip(1.0 - variance / sigma_max, 0.0, None)


def regularized_precision(covariance: np.ndarray, w_max: np.ndarray) -> np.ndarray:
    """``(Sigma_t + lambda diag(1 / w_max))^-1`` ``(T, m, m)`` of GMR covariances ``(T, m, m)``
    (``1 / w_max``: the tolerances squared; lambda :data:`REGULARIZATION`)."""
    floor = REGULARIZATION / np.asarray(w_max, float)
    return np.linalg.inv(covariance + np.diag(floor))


def weighting(
    similarity: str,
    variance: np.ndarray,
    covariance: np.ndarray | None,
    w_max: np.ndarray,
    sigma_max: np.ndarray,
    critical: np.ndarray | None = None,
    importance: np.ndarray | None = None,
) -> np.ndarray:
    """``W_t`` of a similarity weighting, with eq. 21's total weight: per dimension
    (``sum_t W_t[d, d]``) for the diagonal ones, so that only where the weight sits differs;
    over all (in tolerance units, ``sum_t,d`` of the stiffness a dimension keeps when the others
    may adjust, ``1 / (W_t^-1)_dd``) for ``precision``, whose one gain cannot match each.

    - ``variance``: eq. 21 (:func:`similarity_weights`), stiff where the demonstrations agree.
    - ``uniform``: constant in time.
    - ``inverted``: a negative control, rising with the variance: ``min(sigma / sigma_max, 1)``.
    - ``precision``: minimal intervention (Calinon et al.): one gain times the regularized GMR
      precision :func:`regularized_precision`, cross-covariances included.
    - ``inverse_variance``: ``1 / (sigma + lambda tolerance^2)`` per dimension, without the
      cross-covariances or eq. 21's ``sigma_max`` ramp.
    - ``oracle``: knowing the task instead of inferring it from the variance: ``w_max`` (eq.
      21's largest) on each ``critical`` step (the phase that decides success), the rest of the
      total evenly on the others. (All of it on the critical steps leaves the attractors before
      them free: the optimizer swings them into the chest.)
    - ``importance``: the task's measured tolerance instead of the demonstrations' agreement:
      on each ``critical`` step one gain times ``importance`` (a quadratic form in tolerance
      units, e.g. :mod:`imitate.evaluation.sensitivity`'s), with eq. 21's total over those steps
      (counted as for ``precision``); eq. 21 on the others. Meant as the upper reference:
      what a weighting that knew the task's tolerance would do.

    Args:
        similarity: One of :data:`SIMILARITIES`.
        variance: GMR variances ``(T, m)``.
        covariance: GMR covariances ``(T, m, m)``, read by ``precision`` only (``None`` for
            the others).
        w_max: ``(m,)`` eq. 21's weights at zero variance (``1 / tolerance^2``), > 0 for
            ``precision`` and ``inverse_variance``.
        sigma_max: ``(m,)`` eq. 21's variances where the weight reaches zero.
        critical: ``(T,)`` bool, the steps that decide success; read by ``oracle`` and
            ``importance``.
        importance: ``(m, m)`` symmetric positive definite, tolerance units (``1`` on the
            diagonal is eq. 21's ``w_max``); read by ``importance`` only.

    Returns:
        ``(T, m)`` diagonals of ``W_t``, or ``(T, m, m)`` matrices for ``precision`` and
        ``importance``.

    Raises:
        ImitateError: an unknown ``similarity``, or one without what it reads.
    """
    if similarity not in SIMILARITIES:
        raise ImitateError(f"similarity {similarity!r} unknown; accepted: {SIMILARITIES}")
    w_max = np.asarray(w_max, float)
    ramp = similarity_weights(variance, w_max, sigma_max)
    total = ramp.sum(axis=0)  # (m,) eq. 21's weight per dimension over the steps
    if similarity == "variance":
        return ramp
    if similarity in ("precision", "inverse_variance", "importance") and not np.all(w_max > 0):
        raise ImitateError(
            f"similarity {similarity!r} needs every w_max > 0 (its floor is lambda / w_max); "
            f"got {w_max}: set each w_max > 0, or use a diagonal weighting"
        )
    if similarity == "precision":
        if covariance is None:
            raise ImitateError("similarity 'precision' needs the GMR covariances")
        # each dimension's stiffness when the others adjust, 1 / (Sigma_t + floor)_dd, in
        # units of its w_max; eq. 21's is its own diagonal
        diagonal = np.diagonal(covariance, axis1=1, axis2=2)
        marginal = 1.0 / (diagonal * w_max + REGULARIZATION)
        gain = np.sum(total / w_max) / np.sum(marginal)
        return gain * regularized_precision(covariance, w_max)
    if similarity in ("oracle", "importance"):
        if critical is None or len(critical) != len(variance) or not np.any(critical):
            raise ImitateError(
                f"similarity {similarity!r} needs the steps that decide success, (T,) = "
                f"({len(variance)},) bools, some true; got {critical!r}"
            )
        steps = np.asarray(critical, bool)
        if similarity == "importance":
            return _importance(ramp, w_max, steps, importance)
        stiff = np.minimum(w_max * steps.sum(), total)  # (m,) w_max on each critical step
        rest = (total - stiff) / max(int(np.sum(~steps)), 1)
        return np.where(steps[:, None], stiff / steps.sum(), rest)
    if similarity == "inverse_variance":
        shape = 1.0 / (variance + REGULARIZATION / w_max)
    elif similarity == "uniform":
        shape = np.ones_like(variance)
    else:
        shape = np.clip(variance / np.asarray(sigma_max, float), 0.0, 1.0)
    return shape * total / np.maximum(shape.sum(axis=0), 1e-300)


def _importance(
    ramp: np.ndarray, w_max: np.ndarray, critical: np.ndarray, importance: np.ndarray | None
) -> np.ndarray:
    """``(T, m, m)``: eq. 21's ``ramp`` ``(T, m)`` as diagonal matrices, but on the
    ``critical`` steps one gain times ``importance`` (tolerance units) in task units, the gain
    giving those steps eq. 21's total there (see :func:`weighting`)."""
    m = ramp.shape[1]
    form = None if importance is None else np.asarray(importance, float)
    if (
        form is None or form.shape != (m, m) or not np.all(np.isfinite(form))
        or not np.allclose(form, form.T) or np.linalg.eigvalsh(form)[0] <= 0
    ):
        raise ImitateError(
            f"similarity 'importance' needs the task's measured importance: a symmetric "
            f"positive definite ({m}, {m}) form in tolerance units; got {importance!r:.80}"
        )
    scale = np.sqrt(w_max)  # 1 / tolerance per dimension
    marginal = 1.0 / np.diag(np.linalg.inv(form))  # tolerance units, per critical step
    gain = np.sum(ramp[critical] / w_max) / (critical.sum() * marginal.sum())
    weights = np.einsum("ti,ij->tij", ramp, np.eye(m))
    weights[critical] = gain * form * np.outer(scale, scale)
    return weights


class Similarity:
    """Eqs. 20-22 on the target trajectory.

    Args:
        mean: GMR mean ``(T + 1, m)``.
        weights: ``W_t``: its diagonals ``(T + 1, m)`` (:func:`similarity_weights`) or whole
            matrices ``(T + 1, m, m)`` (:func:`weighting`'s ``precision``).
        dt: Step [s].
    """

    def __init__(self, mean: np.ndarray, weights: np.ndarray, dt: float):
        self.mean, self.weights, self.dt = mean, weights, dt

    def __call__(self, result: Rollout, x: np.ndarray):
        err = x - self.mean
        if self.weights.ndim == 3:
            werr = np.einsum("tij,tj->ti", self.weights, err)
        else:
            werr = self.weights * err
        gq = np.zeros_like(result.q)
        return self.dt * float(np.sum(werr * err)), gq, 2.0 * self.dt * werr


def potential(d: np.ndarray, epsilon: float) -> tuple[np.ndarray, np.ndarray]:
    """CHOMP's potential and its derivative for signed distances ``d`` [m]."""
    inside = (d >= 0) & (d < epsilon)
    quadratic = np.where(inside, (d - epsilon) ** 2 / (2 * epsilon), 0.0)
    value = np.where(d < 0, 0.5 * epsilon - d, quadratic)
    slope = np.where(d < 0, -1.0, np.where(inside, (d - epsilon) / epsilon, 0.0))
    return value, slope


class Collision:
    """Collision and proximity cost from the rollout's signed distances.

    Args:
        margin: Clearance [m] below which a pair counts as colliding.
        epsilon: Width [m] of the proximity zone above ``margin``.
        dt: Step [s].
    """

    def __init__(self, margin: float, epsilon: float, dt: float):
        if not margin >= 0 or not epsilon > 0:
            raise ImitateError(f"margin must be >= 0 and epsilon > 0 [m]; got {margin}, {epsilon}")
        self.margin, self.epsilon, self.dt = margin, epsilon, dt

    @property
    def distmax(self) -> float:
        """Distance [m] beyond which pairs cost nothing."""
        return self.margin + self.epsilon

    def __call__(self, result: Rollout, x: np.ndarray):
        gq = np.zeros_like(result.q)
        total = 0.0
        # Each sample: its distances, its weight and the steps its gradient goes to, with their
        # shares. The samples along a step weigh together as much as one at a step; a sample's
        # gradient goes to the two ends by its place between them.
        samples: list[tuple[Distances, float, tuple[tuple[int, float], ...]]] = [
            (d, 1.0, ((t, 1.0),)) for t, d in enumerate(result.distances) if len(d.dist)
        ]
        along = np.bincount([t for t, _, _ in result.between], minlength=len(result.q))
        samples += [
            (d, 1.0 / along[t], ((t, 1.0 - s), (t + 1, s)))
            for t, s, d in result.between
            if len(d.dist)
        ]
        if samples:  # the potential of all samples' pairs at once, then summed per sample
            value, slope = potential(
                np.concatenate([d.dist for d, _, _ in samples]) - self.margin, self.epsilon
            )
            start = 0
            for d, weight, steps in samples:
                stop = start + len(d.dist)
                total += weight * float(value[start:stop].sum())
                g = weight * (slope[start:stop] @ d.jac)
                for t, share in steps:
                    gq[t] += share * g
                start = stop
        return 0.5 * self.dt * total, 0.5 * self.dt * gq, np.zeros_like(x)


class JointLimits:
    """Joint-limit proximity: ``sum_t H(q_t) dt``."""

    def __init__(self, limits: JointLimitCost, dt: float):
        self.limits, self.dt = limits, dt

    def __call__(self, result: Rollout, x: np.ndarray):
        value, grad, _ = self.limits(result.q)
        return self.dt * float(value.sum()), self.dt * grad, np.zeros_like(x)


class PathLength:
    """Joint-space trajectory length ``sum_t |q_{t+1} - q_t|^2 / dt`` [rad^2/s]."""

    def __init__(self, dt: float):
        self.dt = dt

    def __call__(self, result: Rollout, x: np.ndarray):
        step = np.diff(result.q, axis=0)
        gq = np.zeros_like(result.q)
        gq[1:] += 2.0 * step / self.dt
        gq[:-1] -= 2.0 * step / self.dt
        return float(np.sum(step * step)) / self.dt, gq, np.zeros_like(x)


class JointAcceleration:
    """Joint accelerations above what the position servos follow: ``sum_t sum_i max(|a_ti| -
    a_max, 0)^2 dt`` [rad^2/s^3] with ``a_t = (q_{t+1} - 2 q_t + q_{t-1}) / dt^2`` and the robot
    at rest before the start and after the end; zero for a movement within ``a_max``."""

    def __init__(self, a_max: float, dt: float):
        self.a_max, self.dt = a_max, dt

    def __call__(self, result: Rollout, x: np.ndarray):
        q = np.concatenate([result.q[:1], result.q, result.q[-1:]])
        acc = np.diff(q, 2, axis=0) / self.dt**2
        excess = np.sign(acc) * np.maximum(np.abs(acc) - self.a_max, 0.0)
        g = 2.0 * excess / self.dt  # d/dq of dt * excess^2 through a_t, before the stencil
        gq = np.zeros_like(q)
        gq[:-2] += g
        gq[1:-1] -= 2.0 * g
        gq[2:] += g
        gq[1] += gq[0]  # the rest before the start is q_0, after the end q_T
        gq[-2] += gq[-1]
        return self.dt * float(np.sum(excess * excess)), gq[1:-1], np.zeros_like(x)
