"""The primary endpoint per block of teachers: the power line checked against the noncentral t
distribution (scipy), the GEE model against the odds ratio worked by hand, the permutation
floor against the test itself, and the verdict's cases."""

import math

import numpy as np
import pytest
from scipy import stats

from imitate.errors import ImitateError
from imitate.evaluation.inference import teacher_effect
from imitate.evaluation.replication import (
    LEVEL,
    POWER,
    gee_effect,
    parse_primary,
    power,
    replication,
    verdict,
)


def t_power(effect: float, n: int) -> float:
    """Power of the two-sided one-sample t test of ``n`` teachers at a standardized ``effect``,
    from the noncentral t distribution."""
    critical = stats.t.ppf(1 - LEVEL / 2, n - 1)
    shift = effect * math.sqrt(n)
    return float(stats.nct.sf(critical, n - 1, shift) + stats.nct.cdf(-critical, n - 1, shift))


@pytest.mark.parametrize("n", [5, 10, 25])
def test_the_smallest_detectable_difference_has_the_stated_power(n):
    d = np.random.default_rng(n).normal(0.05, 0.15, n)
    result = power(d)
    sd = np.std(d, ddof=1)
    assert t_power(result["detectable"] / sd, n) == pytest.approx(POWER, abs=1e-3)
    needed = result["teachers_needed"]  # the fewest teachers this mean needs
    effect = abs(d.mean()) / sd
    assert t_power(effect, needed) >= POWER - 1e-6 > t_power(effect, needed - 1)


def test_the_permutation_floor_is_the_exact_tests_smallest_p():
    for n in (4, 5, 6):
        d = np.linspace(0.1, 0.2, n)  # every teacher favours a: the smallest p there is
        floor = power(d)["permutation_floor"]
        assert teacher_effect(d)["p"] == pytest.approx(floor) == 2 / 2**n
        assert power(d)["floor_above_level"] == (floor > LEVEL)
    assert power(np.zeros(5))["detectable"] is None  # no spread: nothing to say


def test_gee_odds_ratio_is_the_pooled_one_for_balanced_teachers():
    rng = np.random.default_rng(0)
    teachers = np.repeat(np.arange(6), 40)
    a, b = rng.random(240) < 0.7, rng.random(240) < 0.45
    result = gee_effect(a, b, teachers)
    odds = (a.mean() / (1 - a.mean())) / (b.mean() / (1 - b.mean()))
    assert result["odds_ratio"] == pytest.approx(odds, rel=1e-6)
    assert result["ci95"][0] < odds < result["ci95"][1] and result["p"] < 0.05
    always = gee_effect(np.ones(240, bool), b, teachers)
    assert always["odds_ratio"] is None and "separation" in always["note"]


def test_blocks_and_verdicts():
    teachers = np.repeat([0, 1, 2, 3, 1000, 1001, 1002, 1003], 10)
    better = np.tile(np.arange(10) < 8, 8)  # 80 % in every teacher
    worse = np.tile(np.arange(10) < 3, 8)  # 30 %, but a little noise per teacher below
    worse[::17] = True
    result = replication({"variance": better, "uniform": worse}, teachers,
                         ("variance", "uniform"), range(1000, 1100))
    assert result["development"]["teachers"] == [0, 1, 2, 3]
    assert result["confirmation"]["teachers"] == [1000, 1001, 1002, 1003]
    assert len(result["all"]["teachers"]) == 8 and result["verdict"] == "replicated"
    # means over the teachers: 8 of 10 each; 3 of 10 each and two flipped of 40 (17, 34)
    assert result["development"]["success"] == {"variance": 0.8,
                                                "uniform": pytest.approx(0.3 + 2 / 40)}
    reversed_ = replication({"variance": np.where(teachers < 1000, better, worse),
                             "uniform": np.where(teachers < 1000, worse, better)}, teachers,
                            ("variance", "uniform"), range(1000, 1100))
    assert reversed_["verdict"] == "reversed"
    alone = replication({"variance": better, "uniform": worse}, teachers,
                        ("variance", "uniform"), ())
    assert alone["confirmation"] is None and alone["verdict"] == "no confirmation block"
    block = {"effect": {"ci95": [-0.1, 0.2]}}
    assert verdict(block, block) == "no development verdict"
    assert verdict({"effect": {"ci95": [0.1, 0.2]}}, block) == "not replicated"


def test_primary_is_two_of_the_compared_weightings():
    assert parse_primary("precision-variance", ("variance", "precision")) == (
        "precision", "variance")
    for text in ("variance", "variance-variance", "variance-oracle", ""):
        with pytest.raises(ImitateError, match="--primary .* not accepted: A-B"):
            parse_primary(text, ("variance", "uniform"))
