"""BIC model selection (eqs. 5-7): fast heuristic against EM, the sweep's EM starts, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from imitate.errors import ImitateError
from imitate.learning._em import _e_step, _factor, _sorted_transposed
from imitate.learning.bic import _LOG_NEGLIGIBLE, bic_sweep
from imitate.learning.gmm import GMM, _bic, kmeans_parameters


def test_fast_bic_is_the_bic_of_its_kmeans_clusters_and_above_full(demo_data):
    k_max = 12
    fast = bic_sweep(demo_data, k_max, "fast")
    full = bic_sweep(demo_data, k_max, "full").curve
    for k in (1, 5, 12):
        init = kmeans_parameters(demo_data, fast.labels[k - 1], k)
        np.testing.assert_allclose(
            fast.curve[k - 1], GMM.from_parameters(*init).bic(demo_data), rtol=1e-9
        )
    # EM from converged K-means starts fits better than the fast heuristic's clusters (the
    # paper's Fig. 5: the fast curve lies above).
    assert np.all(full <= fast.curve + 1e-6 * np.abs(fast.curve))


def test_fast_bic_keeping_unchanged_clusters_densities_is_exact():
    """The fast sweep keeps the log-densities of clusters that did not change from one K to the
    next; its curve equals, bit for bit, the mixtures' likelihoods computed afresh for every K
    (on random walks about half of the clusters carry over)."""
    rng = np.random.default_rng(3)
    walks = np.cumsum(rng.normal(size=(3, 400, 4)), axis=1).reshape(-1, 4)
    X = np.column_stack([np.tile(np.linspace(0.0, 4.0, 400), 3), walks])
    sweep = bic_sweep(X, 20, "fast")
    xt = _sorted_transposed(X)[0]
    nothing = np.empty((0, 0)), np.empty((0, 0), dtype=bool)
    for k in range(1, 21):
        weights, means, cov = kmeans_parameters(X, sweep.labels[k - 1], k)
        prec_chol, log_coef = np.zeros_like(cov), np.empty(k)
        assert _factor(weights, cov, prec_chol, log_coef)
        fresh = _e_step(xt, means, prec_chol, log_coef, _LOG_NEGLIGIBLE, np.empty((0, k)),
                        *nothing)
        total = 0.0
        for value in fresh:  # in order, as the sweep sums
            total += value
        assert sweep.curve[k - 1] == _bic(total, k, X.shape[1], X.shape[0])


def test_bic_sweep_keeps_the_em_start_of_every_k(demo_data):
    sweep = bic_sweep(demo_data, 8, "full")
    assert sweep.k == np.argmin(sweep.curve) + 1
    for got, want in zip(sweep.initial_parameters(demo_data),
                         GMM(sweep.k).initial_parameters(demo_data), strict=True):
        np.testing.assert_array_equal(got, want)


def test_bad_input_is_rejected():
    X = np.random.default_rng(0).normal(size=(10, 2))
    with pytest.raises(ImitateError, match=r"more components \(30\) than samples \(10\)"):
        bic_sweep(X, k_max=30)
    with pytest.raises(ImitateError, match="method must be one of"):
        bic_sweep(X, 3, method="slow")
