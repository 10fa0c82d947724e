"""Inference at the level of the learned model: a weighting's effect with its interval over
teachers.

The variations one learned model reproduces share that model, so they are not independent
evidence about a weighting: a pooled test over them speaks of those models only. A teacher
(another session of demonstrations, so another learned model) is the unit here: each teacher's
paired difference between two weightings (its success rate, mean score, ...) is one observation,
and :func:`teacher_effect` gives their mean with a t interval and an exact sign-flip permutation
test over teachers. :func:`ed50` finds where a dose-response curve (success against a swept
setting) crosses 50 %, with a bootstrap interval over teachers.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import stats

__all__ = ["crossing", "ed50", "mean_ci", "teacher_effect"]

_EXACT_TEACHERS = 16  # up to this many teachers the permutation test enumerates every sign
_RESAMPLES = 9999  # sign flips drawn beyond it; bootstrap resamples of ED50
_LEVEL = 0.5  # the success rate whose dose ED50 is


def mean_ci(values: np.ndarray) -> tuple[float, list[float] | None]:
    """The mean of per-teacher values ``(n,)`` and its 95 % t interval over teachers (``None``
    below two teachers, or where they all agree: no spread to infer from)."""
    v = np.asarray(values, dtype=float)
    mean = float(np.mean(v)) if len(v) else math.nan
    if len(v) < 2 or np.ptp(v) == 0:
        return mean, None
    return mean, [float(b) for b in stats.ttest_1samp(v, 0.0).confidence_interval(0.95)]


def teacher_effect(differences: np.ndarray) -> dict:
    """The mean of per-teacher paired differences ``(n,)`` (weighting a minus b) and what it
    says beyond these teachers.

    Returns:
        ``teachers`` (n), ``mean``, ``ci95`` (a t interval over teachers, :func:`mean_ci`),
        ``p`` (two-sided, exact sign-flip
        permutation test of the mean, sampled beyond 16 teachers; 1 without a difference,
        ``None`` below two teachers), and
        how many teachers favour ``a`` (``a_higher``), ``b`` (``b_higher``) or neither
        (``ties``).
    """
    d = np.asarray(differences, dtype=float)
    n = len(d)
    mean, ci = mean_ci(d)
    if n < 2:
        p = None
    elif np.all(d == 0):
        p = 1.0
    else:
        exact = n <= _EXACT_TEACHERS
        p = float(stats.permutation_test(
            (d,), lambda x, axis: np.mean(x, axis=axis), vectorized=True,
            permutation_type="samples", n_resamples=2**n if exact else _RESAMPLES,
            alternative="two-sided", rng=np.random.default_rng(0),
        ).pvalue)
    return {
        "teachers": n, "mean": mean, "ci95": ci, "p": p,
        "a_higher": int(np.sum(d > 0)), "b_higher": int(np.sum(d < 0)),
        "ties": int(np.sum(d == 0)),
    }


def crossing(levels: np.ndarray, curve: np.ndarray, rising: bool | None) -> float:
    """The level where ``curve`` ``(L,)`` over increasing ``levels`` ``(L,)`` passes 50 % for
    good in its direction (upwards if ``rising``, else downwards): its last crossing that way,
    interpolated linearly (in ``log`` of the level when all are positive). ``-inf`` when it is
    past 50 % at every level (below the smallest), ``inf`` when it ends short of it (beyond the
    largest); ``nan`` for a ``None`` direction (curves that do not move)."""
    if rising is None:
        return math.nan
    x = np.log(levels) if np.all(levels > 0) else np.asarray(levels, float)
    past = (np.asarray(curve, float) - _LEVEL) * (1.0 if rising else -1.0)  # >= 0: past 50 %
    if past[-1] < 0:
        return math.inf
    short = np.flatnonzero(past < 0)
    if not len(short):
        return -math.inf
    i = short[-1]  # the last level short of 50 %; the next one is past it
    share = past[i] / (past[i] - past[i + 1])
    return float(_back(x[i] + share * (x[i + 1] - x[i]), levels))


def ed50(levels: np.ndarray, rates: np.ndarray, rising: bool | None) -> dict:
    """The dose at 50 % success of a weighting, from its success rates ``(teachers, L)`` at
    ``levels`` ``(L,)`` with success ``rising`` with the level or falling (one direction for
    every weighting of a sweep): where the mean over teachers crosses 50 % (:func:`crossing`),
    with a 95 % percentile bootstrap interval over teachers (resampled with replacement, seed 0;
    ``None`` below two teachers), and each teacher's own crossing. Values beyond the swept
    levels are ``inf`` or ``-inf``.

    Returns:
        ``{"ed50", "ci95", "by_teacher"}``.
    """
    levels, rates = np.asarray(levels, float), np.asarray(rates, float)
    ci = None
    if len(rates) >= 2 and rising is not None:
        picks = np.random.default_rng(0).integers(0, len(rates), size=(_RESAMPLES, len(rates)))
        boot = np.array([crossing(levels, rates[p].mean(axis=0), rising) for p in picks])
        ci = [float(v) for v in np.quantile(boot, [0.025, 0.975], method="inverted_cdf")]
    return {
        "ed50": crossing(levels, rates.mean(axis=0), rising),
        "ci95": ci,
        "by_teacher": [crossing(levels, r, rising) for r in rates],
    }


def _back(x: float, levels: np.ndarray) -> float:
    """``x`` on the levels' own scale (undoing :func:`crossing`'s log)."""
    return math.exp(x) if np.all(levels > 0) else x
