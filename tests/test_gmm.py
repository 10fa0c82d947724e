"""GMM (eqs. 3-12): EM against scikit-learn, BIC of a model, properties, bad input."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sklearn.mixture import GaussianMixture

from imitate.errors import ImitateError
from imitate.learning.gmm import GMM, kmeans_parameters, n_parameters
from imitate.learning.kmeans import kmeans


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
    log_p = gmm.score_samples(X)
    assert np.all(resp >= 0) and np.all(np.isfinite(log_p))
    # exp(log pi_k N_k - log p) loses about eps * |log p| to rounding for far-away samples
    # (|log p| reaches 1e5 here): the sums may miss 1 by that much and no more.
    tolerance = 4 * np.finfo(float).eps * np.maximum(1.0, np.abs(log_p))
    assert np.all(np.abs(resp.sum(axis=1) - 1.0) <= tolerance)


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
    with pytest.raises(ImitateError, match="non-finite value .* sample 3"):
        GMM(2).fit(np.where(np.arange(20).reshape(10, 2) == 6, np.nan, X))
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
