"""The minimizers of the attractor optimization, over an array of variables: iRprop- (sign-based,
robust to the collision cost's kinks) and L-BFGS (scipy). Each evaluation is passed to a
callback, which keeps the best iterate.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.optimize import minimize

__all__ = ["lbfgs", "rprop"]

# ``evaluate(v) -> (total, values by cost, gradient like v)``; ``record(v, total, values)``.
Evaluate = Callable[[np.ndarray], tuple[float, dict, np.ndarray]]
Record = Callable[[np.ndarray, float, dict], None]

# iRprop- step factors: growth while a gradient keeps its sign, shrink on a change, and the
# largest step as a multiple of the initial one.
_RPROP_GROW, _RPROP_SHRINK, _RPROP_MAX = 1.2, 0.5, 50.0


def rprop(
    evaluate: Evaluate, v0: np.ndarray, step: np.ndarray, *, max_iter: int, tol: float,
    patience: int, record: Record,
) -> bool:
    """iRprop-: per-coordinate steps (initially ``step``, shaped like ``v0``) grow by 1.2 while
    the gradient keeps its sign, halve on a sign change (and skip that coordinate once). Stops
    when the best total of the last ``patience`` iterations improved on the best before them
    by at most ``tol`` (relative). Returns whether it stopped so (converged)."""
    v = v0.copy()
    step = step.copy()
    step_max = _RPROP_MAX * step
    prev = np.zeros_like(v)
    total, values, grad = evaluate(v)
    record(v, total, values)
    totals = [total]
    for _ in range(max_iter):
        if not np.all(np.isfinite(grad)):
            return False
        sign = prev * grad
        step = np.where(sign > 0, np.minimum(step * _RPROP_GROW, step_max), step)
        step = np.where(sign < 0, step * _RPROP_SHRINK, step)
        grad = np.where(sign < 0, 0.0, grad)
        v = v - np.sign(grad) * step
        prev = grad
        total, values, grad = evaluate(v)
        record(v, total, values)
        totals.append(total)
        if len(totals) > patience:
            old, new = min(totals[:-patience]), min(totals)
            if old - new <= tol * abs(old):
                return True
    return False


def lbfgs(
    evaluate: Evaluate, v0: np.ndarray, *, max_iter: int, tol: float, record: Record
) -> bool:
    """L-BFGS-B (scipy) from ``v0``, relative function tolerance ``tol / 100``. Returns whether
    scipy reports success."""

    def fun(flat):
        total, values, grad = evaluate(flat.reshape(v0.shape))
        record(flat.reshape(v0.shape), total, values)
        return total, grad.ravel()

    result = minimize(
        fun, v0.ravel(), jac=True, method="L-BFGS-B",
        options={"maxiter": max_iter, "ftol": tol * 1e-2},
    )
    return bool(result.success)
