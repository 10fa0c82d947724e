"""GMM (eqs. 3-12): EM against scikit-learn, BIC, K-means, properties, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.cluster import KMeans
from sklearn.mixture import GaussianMixture

from imitate.dtw import align
from imitate.errors import ImitateError
from imitate.gmm import (
    GMM,
    _assign_all,
    _lloyd,
    bic_sweep,
    kmeans,
    kmeans_parameters,
    n_parameters,
    select_components,
)
from imitate.learning import time_stacked
from imitate.synthetic import pouring_demos


@pytest.fixture(scope="module")
def demo_data() -> np.ndarray:
    """Aligned synthetic pouring demonstrations as (t, x) samples, shape (~2400, 8)."""
    sd = pouring_demos()
    return time_stacked(list(align(sd.demos).aligned), sd.rate)


def _sklearn_from(init, k, **kwargs) -> GaussianMixture:
    weights, means, cov = init
    return GaussianMixture(
        k, covariance_type="full", weights_init=weights, means_init=means,
        precisions_init=np.linalg.inv(cov), **kwargs,
    )


@pytest.mark.parametrize("k", [1, 4, 9, 30])
def test_em_reaches_sklearn_log_likelihood_from_the_same_start(demo_data, k):
    ours = GMM(k, tol=1e-3, max_iter=100)
    init = ours.initial_parameters(demo_data)
    ours.fit(demo_data)
    ref = _sklearn_from(init, k, tol=1e-3, max_iter=100, reg_covar=1e-6).fit(demo_data)
    np.testing.assert_allclose(ours.score(demo_data), ref.score(demo_data), rtol=1e-6)
    assert ours.n_iter_ == ref.n_iter_
    np.testing.assert_allclose(ours.bic(demo_data), ref.bic(demo_data), rtol=1e-6)


def test_fit_from_given_start_matches_sklearn_on_badly_scaled_data():
    rng = np.random.default_rng(0)
    X = np.vstack([rng.normal(0, 1, (300, 3)), rng.normal(4, 0.5, (200, 3))])
    X[:, 1] *= 1e4  # one dimension 10^4 larger: a naive density would underflow
    init = kmeans_parameters(X, kmeans(X, 2).labels, 2, 1e-6)
    ours = GMM(2, tol=1e-8, max_iter=500).fit_from(X, *init)
    ref = _sklearn_from(init, 2, tol=1e-8, max_iter=500, reg_covar=1e-6).fit(X)
    np.testing.assert_allclose(ours.score(X), ref.score(X), rtol=1e-9)
    np.testing.assert_allclose(ours.predict_proba(X), ref.predict_proba(X), atol=1e-8)


def test_score_and_bic_of_given_parameters_match_sklearn():
    rng = np.random.default_rng(1)
    X = rng.normal(size=(400, 4))
    ref = GaussianMixture(3, random_state=0).fit(X)
    ours = GMM.from_parameters(ref.weights_, ref.means_, ref.covariances_)
    np.testing.assert_allclose(ours.score_samples(X), ref.score_samples(X), rtol=1e-10)
    np.testing.assert_allclose(ours.bic(X), ref.bic(X), rtol=1e-10)
    assert n_parameters(3, 4) == ref._n_parameters()


def test_recovers_separated_clusters():
    rng = np.random.default_rng(2)
    centres = np.array([[0.0, 0.0], [5.0, 0.0], [0.0, 5.0]])
    X = np.vstack([c + rng.normal(scale=0.3, size=(300, 2)) for c in centres])
    gmm = GMM(3).fit(X)
    order = np.argsort(gmm.means_[:, 0] + 2 * gmm.means_[:, 1])
    np.testing.assert_allclose(gmm.means_[order], centres, atol=0.06)
    np.testing.assert_allclose(gmm.weights_, 1 / 3, atol=1e-3)
    assert gmm.converged_


def test_kmeans_matches_sklearn_on_blobs():
    rng = np.random.default_rng(3)
    X = np.vstack([c + rng.normal(scale=0.2, size=(100, 3)) for c in rng.normal(0, 5, (5, 3))])
    ours = kmeans(X, 5)
    ref = KMeans(5, n_init=3, random_state=0).fit(X)
    np.testing.assert_allclose(ours.inertia, ref.inertia_, rtol=1e-9)
    assert len(set(zip(ours.labels.tolist(), ref.labels_.tolist(), strict=True))) == 5


@pytest.mark.parametrize("k", [2, 7, 20])
def test_lloyd_with_bounds_converges_like_plain_lloyd(demo_data, k):
    # Hamerly's bounds only skip distance computations: from the same centres the converged
    # clustering is scikit-learn's plain Lloyd result.
    x = demo_data - demo_data.mean(axis=0)  # as scikit-learn centres it
    init = x[np.random.default_rng(k).choice(len(x), k, replace=False)]
    centers = init.copy()
    labels, upper, lower = np.empty(len(x), dtype=np.intp), np.empty(len(x)), np.empty(len(x))
    _assign_all(x, centers, labels, upper, lower)
    inertia, _ = _lloyd(x, centers, labels, upper, lower, 1000, 0.0)
    ref = KMeans(k, init=init, n_init=1, max_iter=1000, tol=0.0, algorithm="lloyd").fit(x)
    np.testing.assert_array_equal(labels, ref.labels_)
    np.testing.assert_allclose(inertia, ref.inertia_, rtol=1e-9)
    np.testing.assert_allclose(centers, ref.cluster_centers_, rtol=1e-9, atol=1e-12)


def test_fast_bic_is_the_bic_of_the_kmeans_start_and_never_below_full(demo_data):
    k_max = 12
    _, fast = select_components(demo_data, k_max, "fast")
    _, full = select_components(demo_data, k_max, "full")
    for k in (1, 5, 12):
        init = GMM(k).initial_parameters(demo_data)
        np.testing.assert_allclose(
            fast[k - 1], GMM.from_parameters(*init).bic(demo_data), rtol=1e-9
        )
    # EM from the K-means start never lowers the likelihood: the full curve lies below.
    assert np.all(full <= fast + 1e-6 * np.abs(fast))


def test_bic_sweep_keeps_the_em_start_of_every_k(demo_data):
    sweep = bic_sweep(demo_data, 8, "fast")
    k, curve = select_components(demo_data, 8, "fast")
    assert sweep.k == k
    np.testing.assert_array_equal(sweep.curve, curve)
    for got, want in zip(sweep.initial_parameters(demo_data),
                         GMM(sweep.k).initial_parameters(demo_data), strict=True):
        np.testing.assert_array_equal(got, want)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**32 - 1),
    k=st.integers(1, 6),
    scale=st.floats(1e-3, 1e3),
)
def test_property_responsibilities_sum_to_one(seed, k, scale):
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(k, 3, 3))
    cov = (a @ a.transpose(0, 2, 1) + 1e-3 * np.eye(3)) * scale**2
    gmm = GMM.from_parameters(rng.dirichlet(np.ones(k)), rng.normal(size=(k, 3)) * scale, cov)
    X = rng.normal(size=(50, 3)) * scale * 10.0 ** rng.uniform(-2, 3)  # also far away
    resp = gmm.predict_proba(X)
    assert np.all(resp >= 0)
    np.testing.assert_allclose(resp.sum(axis=1), 1.0, rtol=1e-12)
    assert np.all(np.isfinite(gmm.score_samples(X)))


def test_duplicated_points_are_regularised_not_singular():
    X = np.vstack([np.zeros((50, 3)), np.ones((50, 3))])  # two clusters of identical points
    gmm = GMM(2, reg_covar=1e-6).fit(X)
    np.testing.assert_allclose(np.sort(gmm.covariances_[:, 0, 0]), [1e-6, 1e-6])
    assert np.isfinite(gmm.score(X))
    with pytest.raises(ImitateError, match="increase reg_covar"):
        GMM(2, reg_covar=0.0).fit(X)


def test_bad_input_is_rejected():
    X = np.random.default_rng(0).normal(size=(10, 2))
    with pytest.raises(ImitateError, match=r"more components \(11\) than samples \(10\)"):
        GMM(11).fit(X)
    with pytest.raises(ImitateError, match=r"more components \(30\) than samples \(10\)"):
        select_components(X, k_max=30)
    with pytest.raises(ImitateError, match="non-finite value .* sample 3"):
        GMM(2).fit(np.where(np.arange(20).reshape(10, 2) == 6, np.nan, X))
    with pytest.raises(ImitateError, match="method must be one of"):
        select_components(X, 3, method="slow")
    with pytest.raises(ImitateError, match="n_components must be an integer >= 1; got 0"):
        GMM(0)
    with pytest.raises(ImitateError, match="not fitted"):
        GMM(2).score(X)
    with pytest.raises(ImitateError, match="X has 3 dimensions"):
        GMM(2).fit(X).score(np.zeros((4, 3)))
    with pytest.raises(ImitateError, match="sum to 1"):
        GMM.from_parameters([0.5, 0.6], np.zeros((2, 2)), np.tile(np.eye(2), (2, 1, 1)))
    with pytest.raises(ImitateError, match="expected weights"):
        GMM.from_parameters([1.0], np.zeros((1, 2)), np.eye(2))
