"""How well a plan reproduces the learned task: its error in the task's critical phase, where it
deviates, and how far in the demonstrations' own metric."""

from __future__ import annotations

import numpy as np

from imitate.motion.plan import Plan
from imitate.taskspace import TaskSpace

__all__ = ["critical_error", "deviation", "mahalanobis", "task_change"]


def critical_error(plan: Plan, space: TaskSpace, critical: np.ndarray) -> tuple[float, float]:
    """Largest task error of ``plan`` (in ``space``) in the steps ``critical`` ``(T,) bool``
    (the task's critical phase): relative position [m] and tool or target angle [deg]."""
    error = plan.task_error()[critical]
    return (
        float(space.distance(error).max()),
        float(np.degrees(np.abs(error[:, space.angles]).max(initial=0.0))),
    )


def task_change(
    plan: Plan, free: Plan, space: TaskSpace, critical: np.ndarray, phase: str
) -> dict[str, float]:
    """How far ``plan`` (in ``space``) moved the task from ``free`` (the unconstrained reproduction
    of the same model and step): the largest change of the relative positions [m] and of the tool or
    target angle [deg] in the steps ``critical`` ``(T,) bool`` (the task's critical phase, named
    ``phase`` in the keys ``<phase>_m`` and ``<phase>_deg``), and of the relative position in the
    steps whose GMR position variance is at or below its median (where the demonstrations agree)."""
    change = plan.x - free.x
    distance = space.distance(change)
    var = plan.variance[:, space.position_columns].sum(axis=1)
    return {
        f"{phase}_m": float(distance[critical].max()),
        f"{phase}_deg": float(np.degrees(np.abs(change[critical][:, space.angles]).max(
            initial=0.0))),
        "low_variance_m": float(distance[var <= np.median(var)].max()),
    }


def deviation(plan: Plan, first: Plan, space: TaskSpace) -> dict[str, float]:
    """Where ``plan`` (in ``space``) deviates from the GMR mean (paper Fig. 9), against
    ``first`` (the plan of the sweep's first, smallest collision weight; same model and step).

    Returns:
        ``deviation_m2``: squared deviation of the relative position from the GMR mean, summed
        over the steps [m^2]; ``deviation_high_variance_share``: its share in the steps whose
        GMR position variance is above its median; ``change_from_first_m2`` and
        ``change_high_variance_share``: the same for the change from ``first``'s positions;
        ``max_deviation_m``: the largest distance between the two relative positions [m].
    """
    cols = space.position_columns
    dev = np.sum((plan.x[:, cols] - plan.mean[:, cols]) ** 2, axis=1)
    extra = np.sum((plan.x[:, cols] - first.x[:, cols]) ** 2, axis=1)
    var = plan.variance[:, cols].sum(axis=1)
    high = var > np.median(var)
    return {
        "deviation_m2": float(dev.sum()),
        "deviation_high_variance_share": float(dev[high].sum() / max(dev.sum(), 1e-12)),
        "change_from_first_m2": float(extra.sum()),
        "change_high_variance_share": float(extra[high].sum() / max(extra.sum(), 1e-12)),
        "max_deviation_m": float(np.sqrt(extra.max())),
    }


def mahalanobis(plan: Plan, space: TaskSpace) -> dict[str, float]:
    """How many of the demonstrations' standard deviations ``plan`` (in ``space``) sits from
    the GMR mean: the Mahalanobis distance ``d_t`` of ``x_t - mu_t`` under the plan's GMR
    covariance plus the tolerances squared (where the demonstrations
    agree to within a tolerance, an error of one tolerance counts as about one standard
    deviation; the same floor as the ``precision`` weighting's at its lambda of 1, which that
    weighting therefore minimizes: not a neutral measure for it). ``rms``: over the movement."""
    error = plan.task_error()
    floor = np.diag(np.square(space.tolerance))
    d = np.sqrt(np.einsum("ti,tij,tj->t", error, np.linalg.inv(plan.covariance + floor), error))
    return {"rms": float(np.sqrt(np.mean(d * d)))}
