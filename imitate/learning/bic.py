"""Choosing the number of GMM components by the Bayesian information criterion (paper eqs. 5-7).

The paper's eq. 6 divides the log-likelihood by ``N``; combined with eq. 5's penalty ``P ln N``
that makes the penalty dominate and always selects ``K = 1``. We use the total log-likelihood,
the standard BIC (``BIC = -2 sum_i log p(x_i) + P ln N``, as scikit-learn's
``GaussianMixture.bic``), with ``P`` from eq. 7 (:func:`imitate.learning.gmm.n_parameters`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike

from imitate import defaults
from imitate._numba import ensure_writable
from imitate._validation import check_n_components, check_samples
from imitate.errors import ImitateError
from imitate.learning._em import (
    _BLOCK,
    _cluster_parameters,
    _e_step,
    _factor,
    _sorted_transposed,
)
from imitate.learning.gmm import GMM, _bic, _not_positive_definite, kmeans_parameters
from imitate.learning.kmeans import _kmeans_sweep

ensure_writable(__file__)  # before the kernels below are declared

__all__ = ["BIC_METHODS", "DEFAULT_BIC", "BicSweep", "bic_sweep"]

# "full": EM for every K; "fast": the paper's heuristic, the mixture taken from the K-means
# clusters without EM (section IV-B.1).
BIC_METHODS = defaults.BIC_METHODS
DEFAULT_BIC = defaults.DEFAULT_BIC
# The fast sweep's K-means, the paper's "fast K-Means clustering": one chain (not the best of
# n_init), stopped once the centres' summed squared shift is below 1 % of the mean variance
# (100x scikit-learn's tolerance): the clusters have settled to a tenth of the data's spread.
_FAST_CHAINS = 1
_FAST_TOL = 1e-2
# exp(-38) ~ 3e-17 < 2^-53 / 2: negligible next to a term exp(0) = 1 (likelihood-only sums).
_LOG_NEGLIGIBLE = -38.0


@numba.njit(cache=True)
def _cluster_log_likelihoods(
    x: np.ndarray, xt: np.ndarray, labels: np.ndarray, reg_covar: float
) -> np.ndarray:
    """``sum_i log p(x_i)`` (eq. 3) of the mixtures taken from hard clusters (the fast BIC), one
    per clustering ``labels[K - 1]`` of a K-means chain, shape ``(k_max,)``; ``nan`` from the
    first ``K`` with a singular covariance on.

    Terms below ``exp(-38)`` of a sample's largest are left out: added to a sum of at least 1
    they are below half a unit in the last place. ``x`` (N, D) are the samples, ``xt`` the same
    sorted and transposed (see :func:`imitate.learning._em._e_step`). A chain's ``K``-th clustering
    keeps the index of each earlier cluster, and a cluster whose samples did not change has the same
    component: where its weight, mean and factor are those of ``K - 1`` bit for bit, its
    log-densities computed then are kept, not computed again.
    """
    k_max, n = labels.shape
    d = x.shape[1]
    kept = np.empty((k_max, n))
    valid = np.zeros((k_max, -(-n // _BLOCK)), dtype=np.bool_)
    kept_coef = np.full(k_max, np.nan)  # each cluster's component when its rows were kept
    kept_means = np.empty((k_max, d))
    kept_chol = np.empty((k_max, d, d))
    totals = np.full(k_max, np.nan)
    for k in range(1, k_max + 1):
        weights, means, cov = _cluster_parameters(x, labels[k - 1], k, reg_covar)
        prec_chol = np.zeros_like(cov)
        log_coef = np.empty(k)
        if not _factor(weights, cov, prec_chol, log_coef):
            return totals
        for c in range(k):  # element loops: no compiled shape checks (see kmeans._copy_row)
            same = log_coef[c] == kept_coef[c]  # False for a new cluster (nan)
            for e in range(d):
                same = same and means[c, e] == kept_means[c, e]
                for f in range(d):
                    same = same and prec_chol[c, e, f] == kept_chol[c, e, f]
            if not same:
                for block in range(valid.shape[1]):
                    valid[c, block] = False
                kept_coef[c] = log_coef[c]
                for e in range(d):
                    kept_means[c, e] = means[c, e]
                    for f in range(d):
                        kept_chol[c, e, f] = prec_chol[c, e, f]
        log_norm = _e_step(
            xt, means, prec_chol, log_coef, _LOG_NEGLIGIBLE, np.empty((0, k)), kept, valid
        )
        total = 0.0
        for value in log_norm:  # the order of ndarray.sum in numba: no reduction to compile
            total += value
        totals[k - 1] = total
    return totals


@dataclass(frozen=True)
class BicSweep:
    """Outcome of :func:`bic_sweep`.

    Attributes:
        k: The chosen number of components (smallest BIC).
        curve: BIC for ``K = 1..k_max``, shape ``(k_max,)``.
        labels: The K-means clustering of every ``K`` (the EM start), shape ``(k_max, n_samples)``.
    """

    k: int
    curve: np.ndarray
    labels: np.ndarray

    def initial_parameters(
        self, X: ArrayLike, reg_covar: float = 1e-6
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The EM start of the chosen ``K``, the mixture of its K-means clusters (for a ``"full"``
        sweep, what :meth:`GMM.initial_parameters` gives)."""
        return kmeans_parameters(X, self.labels[self.k - 1], self.k, reg_covar)


def bic_sweep(
    X: ArrayLike,
    k_max: int = 30,
    method: str = DEFAULT_BIC,
    seed: int = 0,
    *,
    reg_covar: float = 1e-6,
    n_init: int = 3,
    tol: float = 1e-3,
    max_iter: int = 100,
) -> BicSweep:
    """BIC for ``K = 1..k_max`` and the ``K`` of the smallest one.

    ``"fast"`` is the paper's heuristic (section IV-B.1): a fast K-means (one chain of
    clusterings ``K = 1..k_max`` at a loose tolerance), priors, means and covariances taken from
    the clusters, no EM. ``"full"`` trains a GMM by EM for every ``K`` from the best of
    ``n_init`` converged K-means chains, the start :meth:`GMM.fit` uses. The paper observes that
    the fast heuristic chooses more components than the full one (Fig. 5); that is not
    guaranteed (see the tests).

    Args:
        X: Samples, shape ``(n_samples, n_dims)``, finite.
        k_max: Largest ``K`` tried, ``1 <= k_max <= n_samples``.
        method: One of :data:`BIC_METHODS`.
        seed: Seed of the K-means starts (see :func:`imitate.learning.kmeans.kmeans`).
        reg_covar: Covariance regularisation, see :class:`~imitate.learning.gmm.GMM`.
        n_init: Number of independent K-means chains of ``"full"`` (see
            :func:`imitate.learning.kmeans.kmeans`); ``"fast"`` runs one.
        tol: EM tolerance for ``"full"``, see :class:`~imitate.learning.gmm.GMM`.
        max_iter: EM iteration limit for ``"full"``.

    Returns:
        The :class:`BicSweep`: the chosen ``K``, the BIC curve and the K-means clusterings (the
        EM start of the chosen ``K``). For ``"full"``, ``GMM(sweep.k, seed=seed,
        n_init=n_init).fit(X)`` equals EM from ``sweep.initial_parameters(X)`` without
        clustering again.

    Raises:
        ImitateError: On a bad method, ``k_max`` out of range or non-finite samples.
    """
    if method not in BIC_METHODS:
        raise ImitateError(f"method must be one of {BIC_METHODS}; got {method!r}")
    X = check_samples(X)
    check_n_components(k_max, X.shape[0])
    n_samples, n_dims = X.shape
    if method == "fast":
        labels = _kmeans_sweep(X, k_max, _FAST_CHAINS, seed, tol=_FAST_TOL).labels
    else:
        labels = _kmeans_sweep(X, k_max, n_init, seed).labels
    log_likelihoods: np.ndarray | list[float]  # per K
    if method == "fast":
        log_likelihoods = _cluster_log_likelihoods(
            X, _sorted_transposed(X)[0], labels, reg_covar
        )
        if np.isnan(log_likelihoods).any():
            raise _not_positive_definite()
    else:
        log_likelihoods = [
            float(
                GMM(k, reg_covar=reg_covar, tol=tol, max_iter=max_iter)
                .fit_from(X, *kmeans_parameters(X, labels[k - 1], k, reg_covar))
                .score_samples(X)
                .sum()
            )
            for k in range(1, k_max + 1)
        ]
    curve = np.array([
        _bic(log_likelihood, k, n_dims, n_samples)
        for k, log_likelihood in enumerate(log_likelihoods, start=1)
    ])
    return BicSweep(k=int(np.argmin(curve)) + 1, curve=curve, labels=labels)
