"""Whether a comparison's verdict replicates: one primary endpoint declared before the runs, the
development teachers (the seeds the suites and settings were chosen on) and a confirmation block
of teachers from a disjoint seed range that nothing was tuned on, each with its interval over
teachers, what these teachers can detect, and a model over every variation with the teacher as
a cluster.

The endpoint is the paired difference of the success rate between two weightings ``a - b``,
one value per teacher (:func:`~imitate.evaluation.inference.teacher_effect`). Beside it:

- the power line (statsmodels' one-sample t-test power): the smallest difference these teachers
  detect at 80 % power and a two-sided 5 % level, given the spread of their differences, and how
  many teachers the observed difference would need; the exact sign-flip test's floor
  (``2 / 2^n``), which with few teachers lies above the level whatever the data;
- a GEE logistic model of every variation's success on the weighting, the teacher a cluster
  with exchangeable correlation (statsmodels): the odds ratio ``a`` against ``b`` with its
  robust interval (bias-reduced for few clusters), not a hand-written one.

The verdict: the development block decides (its interval excludes 0) or says nothing; the
confirmation block *replicates* it when its mean has the same sign and its interval excludes 0
too, *reverses* it when its interval excludes 0 on the other side, else does not replicate it.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Sequence

import numpy as np

from imitate.errors import ImitateError
from imitate.evaluation.inference import teacher_effect

__all__ = ["CONFIRMATION_SEED", "LEVEL", "POWER", "gee_effect", "parse_primary", "power",
           "replication", "verdict"]

# The first confirmation teacher's seed: development teachers are the run's seed and the next
# ones (0..99), the confirmation block 1000 and up, a range the project never tuned on.
CONFIRMATION_SEED = 1000
LEVEL = 0.05  # two-sided test level
POWER = 0.8  # the power the smallest detectable difference and the teachers needed refer to
# Fewest teachers (clusters) the GEE model is fitted with: its robust covariance, even bias
# reduced (Mancl and DeRouen), needs several.
MIN_CLUSTERS = 5


def parse_primary(text: str, similarities: Sequence[str]) -> tuple[str, str]:
    """``"variance-uniform"`` as the pair ``(a, b)``, both among ``similarities``.

    Raises:
        ImitateError: not two of the compared weightings joined by ``-``.
    """
    a, _, b = str(text).partition("-")
    if not (a in similarities and b in similarities and a != b):
        raise ImitateError(
            f"--primary {text!r} not accepted: A-B, two of the compared weightings "
            f"({', '.join(similarities)}), e.g. {similarities[0]}-{similarities[1]}"
        )
    return a, b


def power(differences: np.ndarray) -> dict:
    """What ``differences`` ``(n,)`` (one per teacher) can tell: ``detectable`` (the smallest
    mean difference detected at :data:`POWER` and a two-sided :data:`LEVEL`, given their
    standard deviation), ``teachers_needed`` (for their observed mean, at that power; ``None``
    without a mean or a spread), ``permutation_floor`` (the exact sign-flip test's smallest
    two-sided p, ``2 / 2^n``) and ``floor_above_level``."""
    # statsmodels loads in a second: here only; its warnings' module first, which sets their
    # filter to "always" when imported (inside the filter below, it would undo it)
    import statsmodels.tools.sm_exceptions  # noqa: F401
    from statsmodels.stats.power import TTestPower

    d = np.asarray(differences, float)
    n = len(d)
    floor = min(1.0, 2.0 / 2.0**n) if n else 1.0
    result = {"detectable": None, "teachers_needed": None, "permutation_floor": floor,
              "floor_above_level": floor > LEVEL}
    sd = float(np.std(d, ddof=1)) if n >= 2 else 0.0
    if sd == 0.0:
        return result
    analysis = TTestPower()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # its root finder's notes on hard cases
        effect = analysis.solve_power(nobs=n, alpha=LEVEL, power=POWER)
        result["detectable"] = float(effect * sd)
        mean = float(np.mean(d))
        if mean != 0.0:
            size = abs(mean) / sd
            needed = float(analysis.solve_power(effect_size=size, alpha=LEVEL, power=POWER))
            if not math.isfinite(needed):  # a large effect: its root lies below 3 teachers
                needed = next((k for k in range(2, 10) if analysis.power(
                    effect_size=size, nobs=k, alpha=LEVEL) >= POWER), math.nan)
            result["teachers_needed"] = int(math.ceil(needed)) if math.isfinite(needed) else None
    return result


def gee_effect(success_a: np.ndarray, success_b: np.ndarray, teachers: np.ndarray) -> dict:
    """A GEE logistic model of success on the weighting (``a`` against ``b``) over every
    variation, clustered by teacher (``(N,)`` each: the pairs of one variation, and its
    teacher's seed): ``odds_ratio`` with its robust (bias-reduced) 95 % interval ``ci95`` and
    ``p``; ``None`` values and a ``note`` where the model is not fitted (fewer than
    :data:`MIN_CLUSTERS` teachers, an arm that always or never succeeds: separation)."""
    import statsmodels.api as sm  # statsmodels loads in a second: here only

    y = np.concatenate([success_a, success_b]).astype(float)
    arm = np.concatenate([np.ones(len(success_a)), np.zeros(len(success_b))])
    groups = np.concatenate([teachers, teachers])
    empty = {"odds_ratio": None, "ci95": None, "p": None}
    if len(set(teachers.tolist())) < MIN_CLUSTERS:
        return {**empty, "note": f"fewer than {MIN_CLUSTERS} teachers"}
    if any(v.min() == v.max() for v in (y[arm == 1], y[arm == 0])):
        return {**empty, "note": "an arm always or never succeeds (separation)"}
    model = sm.GEE(y, sm.add_constant(arm), groups=groups, family=sm.families.Binomial(),
                   cov_struct=sm.cov_struct.Exchangeable())
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore")  # convergence and domain notes: checked below
        fit = model.fit(cov_type="bias_reduced")
        coef, (low, high), p = float(fit.params[1]), fit.conf_int(alpha=LEVEL)[1], fit.pvalues[1]
        spread = float(fit.bse[1])
    if not (np.all(np.isfinite([coef, low, high, p])) and spread > 1e-9):
        return {**empty, "note": "no robust interval (the model did not converge)"}
    return {"odds_ratio": math.exp(coef), "ci95": [math.exp(low), math.exp(high)],
            "p": float(p), "note": None}


def replication(
    success: dict[str, np.ndarray], teachers: np.ndarray, primary: tuple[str, str],
    confirmation: Sequence[int],
) -> dict:
    """The primary endpoint ``a - b`` of ``primary`` over the blocks: ``success`` by weighting
    ``(N,)`` bool (the same variations in the same order for each), ``teachers`` ``(N,)`` their
    teachers' seeds, ``confirmation`` the confirmation teachers' seeds (the others are the
    development block). Returns the endpoint, each block's (``development``,
    ``confirmation``, ``all``) success rates of ``a`` and ``b`` (means over its teachers), its
    teacher-level effect with its power line and GEE model, and the ``verdict``."""
    a, b = primary
    blocks = {
        "development": ~np.isin(teachers, confirmation),
        "confirmation": np.isin(teachers, confirmation),
        "all": np.ones(len(teachers), bool),
    }
    result: dict = {"endpoint": f"{a} - {b}, success rate [per teacher]", "a": a, "b": b}
    for name, inside in blocks.items():
        seeds = sorted(set(teachers[inside].tolist()))
        if not seeds:
            result[name] = None
            continue
        of = [inside & (teachers == t) for t in seeds]
        # rounded: equal rates differ by rounding (2/3 - 1/3 against 1/3), not in truth
        d = np.round([success[a][mine].mean() - success[b][mine].mean() for mine in of], 12)
        result[name] = {
            "teachers": seeds,
            "success": {s: float(np.mean([success[s][mine].mean() for mine in of]))
                        for s in (a, b)},
            "effect": teacher_effect(d),
            "power": power(d),
            "gee": gee_effect(success[a][inside], success[b][inside], teachers[inside]),
        }
    result["verdict"] = verdict(result["development"], result["confirmation"])
    return result


def verdict(development: dict | None, confirmation: dict | None) -> str:
    """``replicated``, ``not replicated``, ``reversed``, ``no development verdict`` (its
    interval includes 0) or ``no confirmation block``."""
    def sign(block: dict) -> int:
        ci = block["effect"]["ci95"]
        return 0 if ci is None or ci[0] <= 0 <= ci[1] else int(np.sign(ci[0]))

    if development is None or sign(development) == 0:
        return "no development verdict"
    if confirmation is None:
        return "no confirmation block"
    told = sign(confirmation)
    if told == sign(development):
        return "replicated"
    return "reversed" if told else "not replicated"
