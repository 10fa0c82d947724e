"""Eq. 21 and the weightings it is compared with: shapes, totals, the coupled fit and gradient."""

from __future__ import annotations

import numpy as np
import pytest

from imitate.demos.oracle import oracle_model
from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.learning import LearningConfig
from imitate.models import humanoid
from imitate.motion import (
    SIMILARITIES,
    AttractorDynamics,
    PlanConfig,
    plan_from_model,
    setup,
    similarity_weights,
    weighting,
)
from imitate.motion.costs import REGULARIZATION
from imitate.motion.replay import planning_task
from imitate.taskspace import EQ1

W_MAX = np.array([4.0, 1.0])
SIGMA_MAX = np.array([2.0, 0.5])


@pytest.fixture(scope="module")
def gmr():
    """A variance ``(T, 2)`` that crosses each ``SIGMA_MAX`` and a covariance with it on the
    diagonal and a correlation of 0.6 between the two dimensions."""
    t = np.linspace(0.0, 1.0, 41)
    variance = np.column_stack([2.5 * t, 0.05 + 0.6 * np.sin(np.pi * t) ** 2])
    off = 0.6 * np.sqrt(variance[:, 0] * variance[:, 1]) + 1e-3
    covariance = np.stack([
        np.array([[v0 + 1e-3, c], [c, v1 + 1e-3]])
        for (v0, v1), c in zip(variance, off, strict=True)
    ])
    return variance, covariance


def test_eq21_is_w_max_at_zero_zero_from_sigma_max_and_linear_between():
    variance = np.array([[0.0, 0.0], [0.5, 0.125], [1.0, 0.25], [2.0, 0.5], [3.0, 0.6]])
    w = similarity_weights(variance, W_MAX, SIGMA_MAX)
    np.testing.assert_allclose(w[0], W_MAX)
    np.testing.assert_allclose(w[1], 0.75 * W_MAX)
    np.testing.assert_allclose(w[2], 0.5 * W_MAX)
    np.testing.assert_array_equal(w[3:], 0.0)
    with pytest.raises(ImitateError, match="sigma_max > 0"):
        similarity_weights(variance, W_MAX, np.array([0.0, 1.0]))


CRITICAL = np.arange(41) >= 30  # the oracle's steps


@pytest.mark.parametrize("similarity", [s for s in SIMILARITIES
                                        if s not in ("precision", "importance")])
def test_each_diagonal_weighting_has_eq21s_total_per_dimension(gmr, similarity):
    variance, covariance = gmr
    w = weighting(similarity, variance, covariance, W_MAX, SIGMA_MAX, critical=CRITICAL)
    total = similarity_weights(variance, W_MAX, SIGMA_MAX).sum(axis=0)
    assert w.shape == variance.shape
    np.testing.assert_allclose(w.sum(axis=0), total, rtol=1e-12)
    assert np.all(w >= 0)


def test_the_oracle_is_stiffest_on_the_critical_steps_and_even_elsewhere(gmr):
    variance, covariance = gmr
    w = weighting("oracle", variance, covariance, W_MAX, SIGMA_MAX, critical=CRITICAL)
    np.testing.assert_allclose(w[CRITICAL], np.broadcast_to(W_MAX, w[CRITICAL].shape))
    np.testing.assert_allclose(w[~CRITICAL], np.broadcast_to(w[0], w[~CRITICAL].shape))
    assert np.all(w[0] < W_MAX)
    with pytest.raises(ImitateError, match="oracle.*needs the steps"):
        weighting("oracle", variance, covariance, W_MAX, SIGMA_MAX)


def test_importance_is_eq21_but_the_measured_form_on_the_critical_steps(gmr):
    variance, covariance = gmr
    form = np.array([[2.0, 0.5], [0.5, 1.0]])  # tolerance units
    w = weighting("importance", variance, covariance, W_MAX, SIGMA_MAX, critical=CRITICAL,
                  importance=form)
    ramp = similarity_weights(variance, W_MAX, SIGMA_MAX)
    assert w.shape == covariance.shape
    np.testing.assert_array_equal(w[~CRITICAL], np.einsum("ti,ij->tij", ramp, np.eye(2))[
        ~CRITICAL])
    in_task_units = form * np.sqrt(np.outer(W_MAX, W_MAX))
    gain = w[CRITICAL][0, 0, 0] / in_task_units[0, 0]
    assert gain > 0
    np.testing.assert_allclose(w[CRITICAL], np.broadcast_to(gain * in_task_units,
                                                            w[CRITICAL].shape), rtol=1e-12)
    # the critical steps keep eq. 21's total there, counted as precision's (tolerance units)
    marginal = 1.0 / np.diagonal(np.linalg.inv(w[CRITICAL]), axis1=1, axis2=2)
    np.testing.assert_allclose(np.sum(marginal / W_MAX), np.sum(ramp[CRITICAL] / W_MAX),
                               rtol=1e-10)
    for bad in (None, np.zeros((2, 2)), np.ones((3, 3)), np.array([[1.0, 2.0], [0.0, 1.0]])):
        with pytest.raises(ImitateError, match="needs the task's measured importance"):
            weighting("importance", variance, covariance, W_MAX, SIGMA_MAX, critical=CRITICAL,
                      importance=bad)
    with pytest.raises(ImitateError, match="importance.*needs the steps"):
        weighting("importance", variance, covariance, W_MAX, SIGMA_MAX, importance=form)


def test_uniform_is_constant_and_inverted_rises_with_the_variance(gmr):
    variance, covariance = gmr
    uniform = weighting("uniform", variance, covariance, W_MAX, SIGMA_MAX)
    np.testing.assert_allclose(uniform, np.broadcast_to(uniform[0], uniform.shape))
    ramp = weighting("variance", variance, covariance, W_MAX, SIGMA_MAX)
    inverted = weighting("inverted", variance, covariance, W_MAX, SIGMA_MAX)
    for d in range(2):
        order = np.argsort(variance[:, d])
        assert np.all(np.diff(inverted[order, d]) >= 0)  # stiff where the demos varied
        assert np.all(np.diff(ramp[order, d]) <= 0)  # eq. 21: the other way round
    assert inverted[0, 0] == 0.0 and ramp[0, 0] == W_MAX[0]


def test_precision_is_one_gain_times_the_regularized_precision(gmr):
    variance, covariance = gmr
    w = weighting("precision", variance, covariance, W_MAX, SIGMA_MAX)
    assert w.shape == covariance.shape
    floor = REGULARIZATION / W_MAX  # lambda times the tolerances squared
    precision = np.linalg.inv(covariance + np.diag(floor))
    gain = w[0, 0, 0] / precision[0, 0, 0]
    np.testing.assert_allclose(w, gain * precision, rtol=1e-10)  # one gain, every step
    assert np.all(w[:, 0, 1] < 0)  # a positive correlation: a negative cross weight
    assert np.all(np.linalg.eigvalsh(w) > 0)
    # the stiffness each dimension keeps when the other adjusts, 1 / (W^-1)_dd, summed in units
    # of w_max, is eq. 21's summed weight in those units
    marginal = 1.0 / np.diagonal(np.linalg.inv(w), axis1=1, axis2=2)
    total = similarity_weights(variance, W_MAX, SIGMA_MAX).sum(axis=0)
    np.testing.assert_allclose(np.sum(marginal / W_MAX), np.sum(total / W_MAX), rtol=1e-10)


def test_precision_is_finite_for_a_singular_covariance():
    """Fewer demonstrations than dimensions: the regularized inverse stays finite."""
    direction = np.array([1.0, 2.0])
    covariance = np.stack([np.outer(direction, direction) * s for s in np.linspace(0, 1, 5)])
    variance = np.diagonal(covariance, axis1=1, axis2=2).copy()
    w = weighting("precision", variance, covariance, W_MAX, np.maximum(variance.max(0), 1e-9))
    assert np.all(np.isfinite(w)) and np.all(np.linalg.eigvalsh(w) > 0)


def test_an_unknown_weighting_is_refused():
    with pytest.raises(ImitateError, match="similarity 'flat' unknown; accepted"):
        PlanConfig(similarity="flat")
    with pytest.raises(ImitateError, match="similarity 'flat' unknown"):
        weighting("flat", np.ones((2, 1)), np.ones((2, 1, 1)), W_MAX[:1], SIGMA_MAX[:1])


def test_coupled_fit_with_diagonal_matrices_equals_the_per_dimension_fit():
    dyn = AttractorDynamics(60, 0.05, np.linspace(0.2, 2.8, 8), 6.0)
    rng = np.random.default_rng(0)
    target = np.cumsum(rng.normal(size=(61, 3)), axis=0) * 0.01
    weights = rng.uniform(0.1, 2.0, size=(61, 3))
    x0 = target[0] + 0.01
    diagonal = dyn.fit(target, x0, weights)
    coupled = dyn.fit(target, x0, np.einsum("ti,ij->tij", weights, np.eye(3)))
    np.testing.assert_allclose(coupled, diagonal, rtol=1e-9, atol=1e-12)


@pytest.fixture(scope="module")
def precision_problem():
    task = planning_task()
    learned = oracle_model(task.gaze, learning=LearningConfig(k_max=8))
    config = PlanConfig(dt=0.1, collision_weight=0.0, similarity="precision")
    start = setup(task, learned, q0=humanoid.rest_pose(), config=config)
    return task, learned, start


def test_precision_similarity_gradient_matches_finite_differences(precision_problem):
    _, _, start = precision_problem
    p = start.problem
    a = start.a0 + np.random.default_rng(1).normal(size=start.a0.shape) * EQ1.tolerance
    grad = p.evaluate(a, ("similarity",))[2]
    fd = np.zeros_like(a)
    for i in range(a.shape[0]):
        for j in range(a.shape[1]):
            e = np.zeros_like(a)
            e[i, j] = EQ1.tolerance[j] * 1e-4
            up = p.evaluate(a + e, ("similarity",), gradient=False)[0]
            down = p.evaluate(a - e, ("similarity",), gradient=False)[0]
            fd[i, j] = (up - down) / (2 * e[i, j])
    assert np.linalg.norm(grad - fd) <= 1e-5 * np.linalg.norm(fd)


def test_every_weighting_plans_and_its_plan_keeps_the_diagonals(precision_problem):
    task, learned, start = precision_problem
    assert start.weights.ndim == 3 and np.any(start.weights[:, 0, 1] != 0)
    for similarity in SIMILARITIES:
        config = PlanConfig(dt=0.1, collision_weight=0.0, max_iter=3, similarity=similarity)
        plan = plan_from_model(task, learned, q0=humanoid.rest_pose(), config=config,
                               critical=get_task("pour").critical, importance=np.eye(7))
        assert plan.weights.shape == plan.mean.shape and np.all(np.isfinite(plan.x))
    with pytest.raises(ImitateError, match="oracle.*needs the task's critical phase"):
        plan_from_model(task, learned, q0=humanoid.rest_pose(),
                        config=PlanConfig(dt=0.1, max_iter=3, similarity="oracle"))
    with pytest.raises(ImitateError, match="needs the task's measured importance"):
        plan_from_model(task, learned, q0=humanoid.rest_pose(),
                        config=PlanConfig(dt=0.1, max_iter=3, similarity="importance"),
                        critical=get_task("pour").critical)
