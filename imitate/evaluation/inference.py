"""Inference at the level of the learned model: a weighting's effect with its interval over
teachers.

The variations one learned model reproduces share that model, so they are not independent
evidence about a weighting: a pooled test over them speaks of those models only. A teacher
(another session of demonstrations, so another learned model) is the unit here: each teacher's
paired difference between two weightings (its success rate, mean pour, ...) is one observation,
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
    below two teachers, ``[mean, mean]`` if they all agree)."""
    v = np.asarray(values, dtype=float)
    mean = float(np.mean(v)) if len(v) else math.nan
    if len(v) < 2:
        return mean, None
    if np.ptp(v) == 0:
        return mean, [mean, mean]
    return mean, [float(b) for b in stats.ttest_1samp(v, 0.0).confidence_interval(0.95)]


def teacher_effect(differences: np.ndarray) -> dict:
    """The mean of per-teacher paired differences ``(n,)`` (weighting a minus b) and what it
    says beyond these teachers.

    Returns:
        ``teachers`` (n), ``mean``, ``ci95`` (a t interval over teachers, ``None`` below two
        teachers; ``[mean, mean]`` if they all agree), ``p`` (two-sided, exact sign-flip
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


def crossing(levels: np.ndarray, curve: np.ndarray, rising: bool) -> float:
    """The level where ``curve`` ``(L,)`` over increasing ``levels`` ``(L,)`` first crosses 50 %,
    interpolated linearly (in ``log`` of the level when all are positive); ``inf`` or ``-inf``
    when it stays on one side: beyond the largest or below the smallest level, as a curve
    ``rising`` (or falling) with the level would cross there."""
    x = np.log(levels) if np.all(levels > 0) else np.asarray(levels, float)
    above = np.asarray(curve, float) - _LEVEL
    for i in range(len(x) - 1):
        if above[i] == 0:
            return float(_back(x[i], levels))
        if above[i] * above[i + 1] < 0 or above[i + 1] == 0:
            share = above[i] / (above[i] - above[i + 1])
            return float(_back(x[i] + share * (x[i + 1] - x[i]), levels))
    if len(x) and above[-1] == 0:
        return float(levels[-1])
    high = bool(np.all(above < 0)) == rising
    return math.inf if high else -math.inf


def ed50(levels: np.ndarray, rates: np.ndarray) -> dict:
    """The dose at 50 % success of a weighting, from its success rates ``(teachers, L)`` at
    ``levels`` ``(L,)``: where the mean over teachers crosses 50 % (:func:`crossing`), with a
    95 % percentile bootstrap interval over teachers (resampled with replacement, seed 0), and
    each teacher's own crossing. Values beyond the swept levels are ``inf`` or ``-inf``.

    Returns:
        ``{"ed50", "ci95", "by_teacher"}``.
    """
    levels, rates = np.asarray(levels, float), np.asarray(rates, float)
    mean = rates.mean(axis=0)
    rising = bool(mean[-1] >= mean[0])
    rng = np.random.default_rng(0)
    picks = rng.integers(0, len(rates), size=(_RESAMPLES, len(rates)))
    boot = np.array([crossing(levels, rates[p].mean(axis=0), rising) for p in picks])
    low, high = np.quantile(boot, [0.025, 0.975], method="inverted_cdf")
    return {
        "ed50": crossing(levels, mean, rising),
        "ci95": [float(low), float(high)],
        "by_teacher": [crossing(levels, r, rising) for r in rates],
    }


def _back(x: float, levels: np.ndarray) -> float:
    """``x`` on the levels' own scale (undoing :func:`crossing`'s log)."""
    return math.exp(x) if np.all(levels > 0) else x
