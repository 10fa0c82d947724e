"""BIC model selection (eqs. 5-7): fast heuristic against EM, the sweep's EM starts, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from imitate.bic import bic_sweep
from imitate.errors import ImitateError
from imitate.gmm import GMM
from imitate.kmeans import kmeans_parameters


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
