"""GMR (eqs. 13-19): cross-check against gmr, the paper's eq. 18, properties, DTW's effect."""

from __future__ import annotations

import gmr as gmr_lib
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from imitate.demos.synthetic import phased_demos
from imitate.errors import ImitateError
from imitate.learning import LearningConfig, learn
from imitate.learning.gmm import GMM
from imitate.learning.gmr import gmr


def _random_gmm(rng: np.random.Generator, k: int, n_dims: int) -> GMM:
    a = rng.normal(size=(k, n_dims, n_dims))
    cov = a @ a.transpose(0, 2, 1) + 0.1 * np.eye(n_dims)
    return GMM.from_parameters(rng.dirichlet(np.ones(k)), rng.normal(size=(k, n_dims)) * 2, cov)


@pytest.mark.parametrize(("seed", "k", "in_dims"), [(0, 1, (0,)), (1, 9, (0,)), (2, 5, (0, 3))])
def test_total_covariance_matches_gmr_library(seed, k, in_dims):
    rng = np.random.default_rng(seed)
    model = _random_gmm(rng, k, 8)
    ref = gmr_lib.GMM(k, priors=model.weights_, means=model.means_,
                      covariances=model.covariances_)
    queries = rng.normal(size=(25, len(in_dims))) * 2
    mean, cov = gmr(model, queries, in_dims=in_dims, covariance="total")
    for n, q in enumerate(queries):
        mvn = ref.condition(list(in_dims), q).to_mvn()
        np.testing.assert_allclose(mean[n], mvn.mean, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(cov[n], mvn.covariance, rtol=1e-8, atol=1e-8)


def test_paper_covariance_follows_eqs_15_to_19_literally():
    rng = np.random.default_rng(4)
    model = _random_gmm(rng, 4, 3)
    ts = np.array([-1.0, 0.3, 2.5])
    mean, cov = gmr(model, ts, covariance="paper")
    for n, t in enumerate(ts):
        beta, x_hat, s_hat = [], [], []
        for w, mu, s in zip(model.weights_, model.means_, model.covariances_, strict=True):
            density = np.exp(-0.5 * (t - mu[0]) ** 2 / s[0, 0]) / np.sqrt(2 * np.pi * s[0, 0])
            beta.append(w * density)
            x_hat.append(mu[1:] + s[1:, 0] / s[0, 0] * (t - mu[0]))  # eq. 15
            s_hat.append(s[1:, 1:] - np.outer(s[1:, 0], s[0, 1:]) / s[0, 0])  # eq. 16
        beta = np.array(beta) / np.sum(beta)  # eq. 19
        np.testing.assert_allclose(mean[n], beta @ np.array(x_hat), rtol=1e-12)  # eq. 17
        np.testing.assert_allclose(
            cov[n], np.einsum("k,kij->ij", beta**2, np.array(s_hat)), rtol=1e-12  # eq. 18
        )


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_dims=st.integers(2, 6),
       covariance=st.sampled_from(["paper", "total"]))
def test_property_lone_component_returns_its_mean(seed, n_dims, covariance):
    rng = np.random.default_rng(seed)
    model = _random_gmm(rng, 1, n_dims)
    mean, cov = gmr(model, model.means_[:, :1], covariance=covariance)
    np.testing.assert_allclose(mean[0], model.means_[0, 1:], rtol=1e-10, atol=1e-12)
    s = model.covariances_[0]
    schur = s[1:, 1:] - np.outer(s[1:, 0], s[0, 1:]) / s[0, 0]
    np.testing.assert_allclose(cov[0], schur, rtol=1e-10, atol=1e-12)


def test_at_a_component_far_from_the_others_returns_that_component():
    rng = np.random.default_rng(5)
    model = _random_gmm(rng, 3, 4)
    means = model.means_.copy()
    means[:, 0] = [0.0, 100.0, 200.0]
    model = GMM.from_parameters(model.weights_, means, model.covariances_)
    mean, _ = gmr(model, [100.0])
    np.testing.assert_allclose(mean[0], means[1, 1:], rtol=1e-12)


def test_dtw_lowers_the_pouring_phase_variance_at_least_twofold():
    sd = phased_demos()
    aligned = learn(
        sd.demos, rate=sd.rate, config=LearningConfig(bic_method="fast", covariance="total")
    )
    k = aligned.gmm.n_components  # chosen by the fast BIC; the same K without DTW
    raw = learn(
        sd.demos, rate=sd.rate,
        config=LearningConfig(n_components=k, use_dtw=False, covariance="total"),
    )
    start, end = sd.act_windows[aligned.alignment.reference]
    pour = (aligned.times >= start) & (aligned.times <= end)
    var_dtw = aligned.variance[pour]
    var_raw = np.diagonal(gmr(raw.gmm, aligned.times[pour], covariance="total")[1], 0, 1, 2)
    # The bottle's tilt (angle around the gaze and its gaze component) is the pouring movement.
    for dim in (3, 4):
        assert var_raw[:, dim].mean() >= 2.0 * var_dtw[:, dim].mean()


def test_bad_input_is_rejected():
    model = _random_gmm(np.random.default_rng(6), 2, 3)
    with pytest.raises(ImitateError, match="covariance must be one of"):
        gmr(model, [0.0], covariance="diag")
    with pytest.raises(ImitateError, match="in_dims must be distinct"):
        gmr(model, [0.0], in_dims=(0, 1, 2))
    with pytest.raises(ImitateError, match="in_dims must be distinct"):
        gmr(model, [0.0], in_dims=(3,))
    with pytest.raises(ImitateError, match=r"t must have shape \(T,\) or \(T, 2\)"):
        gmr(model, [0.0, 1.0], in_dims=(0, 1))
    with pytest.raises(ImitateError, match="finite"):
        gmr(model, [np.nan])
    with pytest.raises(ImitateError, match="not fitted"):
        gmr(GMM(2), [0.0])


def test_learn_rejects_bad_demonstrations():
    demo = np.zeros((40, 7))
    with pytest.raises(ImitateError, match="at least 2 demonstrations; got 1"):
        learn([demo], rate=100.0)
    with pytest.raises(ImitateError, match=r"demos\[1\] has 20 samples, fewer than the 30"):
        learn([demo, demo[:20]], rate=100.0)
    with pytest.raises(ImitateError, match=r"demos\[1\] contains a non-finite"):
        learn([demo, np.full((40, 7), np.nan)], rate=100.0)
    with pytest.raises(ImitateError, match=r"demos\[1\] has 6"):
        learn([demo, np.zeros((40, 6))], rate=100.0)
