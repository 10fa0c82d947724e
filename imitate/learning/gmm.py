r"""Gaussian mixture models with full covariances (paper eqs. 3-12): densities and EM.

Notation (the paper's): ``N`` samples ``x_i`` of dimension ``D`` (time plus task space), ``K``
components with priors ``pi_k``, means ``mu_k`` and covariances ``Sigma_k``.

Numerics follow scikit-learn's ``GaussianMixture(covariance_type="full")``, so that both reach the
same log-likelihood from the same start: densities in log space through the Cholesky factor of
each covariance, responsibilities normalised by log-sum-exp (terms below ``exp(-50)`` of the
largest flushed to zero), and ``reg_covar`` added to the diagonal of every covariance, which also
keeps a cluster of identical samples usable (covariance ``reg_covar * I``). The density and EM
loops are compiled (numba, :mod:`imitate.learning._em`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from imitate._validation import check_samples
from imitate.errors import ImitateError
from imitate.learning._em import (
    _LOG_FLUSH,
    _cluster_parameters,
    _e_step,
    _em_loop,
    _factor,
    _sorted_transposed,
)
from imitate.learning.kmeans import kmeans

__all__ = ["GMM", "exp_flushed", "kmeans_parameters", "n_parameters"]

def n_parameters(n_components: int, n_dims: int) -> int:
    """Number of free parameters ``P`` of a full-covariance GMM (eq. 7)."""
    return (n_components - 1) + n_components * (n_dims + n_dims * (n_dims + 1) // 2)


def kmeans_parameters(
    X: ArrayLike, labels: ArrayLike, n_components: int, reg_covar: float = 1e-6
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """GMM parameters from hard cluster labels (the paper's initialisation and fast heuristic).

    Args:
        X: Samples, shape ``(n_samples, n_dims)``.
        labels: Cluster of each sample, shape ``(n_samples,)``, values in ``[0, n_components)``.
        n_components: Number of components ``K``.
        reg_covar: Added to the diagonal of every covariance, ``>= 0``.

    Returns:
        ``(weights, means, covariances)`` of shapes ``(K,)``, ``(K, D)``, ``(K, D, D)``:
        cluster fractions, centroids and (biased) cluster covariances plus ``reg_covar * I``.
    """
    X = check_samples(X)
    return _cluster_parameters(X, np.asarray(labels, dtype=np.intp), n_components, reg_covar)


def _bic(log_likelihood: float, n_components: int, n_dims: int, n_samples: int) -> float:
    """BIC from the total log-likelihood [nats] (eq. 5, see :mod:`imitate.learning.bic`)."""
    return -2.0 * log_likelihood + n_parameters(n_components, n_dims) * np.log(n_samples)


def _not_positive_definite() -> ImitateError:
    return ImitateError(
        "a component covariance is not positive definite (singular data such as duplicated "
        "points or a constant dimension); increase reg_covar, use fewer components or "
        "rescale the data"
    )


def exp_flushed(a: np.ndarray) -> np.ndarray:
    """``exp(a)`` with entries where ``a < -50`` set to exactly 0 (see ``_LOG_FLUSH``)."""
    return np.exp(a, out=np.zeros_like(a), where=a >= _LOG_FLUSH)


class GMM:
    """Gaussian mixture model with full covariances, trained by EM from a K-means start.

    Args:
        n_components: Number of components ``K >= 1``.
        reg_covar: Added to the diagonal of every covariance (in the squared units of the data),
            ``>= 0``; keeps components of duplicated or collinear points non-singular.
        tol: EM stops when the mean log-likelihood per sample changes by less than this [nats].
        max_iter: Maximum number of EM iterations, ``>= 1``.
        n_init: Number of K-means starts for the initialisation (see
            :func:`imitate.learning.kmeans.kmeans`).
        seed: Seed of the K-means starts (see :func:`imitate.learning.kmeans.kmeans`).

    Attributes:
        weights_: Priors ``pi_k``, shape ``(K,)``, summing to 1.
        means_: Means ``mu_k``, shape ``(K, D)``.
        covariances_: Covariances ``Sigma_k``, shape ``(K, D, D)``.
        precisions_: Inverse covariances, shape ``(K, D, D)``.
        converged_: Whether EM met ``tol`` within ``max_iter`` iterations.
        n_iter_: Number of EM iterations run.
        lower_bound_: Mean log-likelihood per sample before the last M-step [nats].

    Examples:
        >>> rng = np.random.default_rng(0)
        >>> X = np.vstack([rng.normal(0.0, 0.1, (200, 2)), rng.normal(3.0, 0.1, (200, 2))])
        >>> gmm = GMM(2).fit(X)
        >>> np.allclose(np.sort(gmm.means_[:, 0]), [0.0, 3.0], atol=0.05)
        True
    """

    def __init__(
        self,
        n_components: int,
        *,
        reg_covar: float = 1e-6,
        tol: float = 1e-3,
        max_iter: int = 100,
        n_init: int = 3,
        seed: int = 0,
    ) -> None:
        if not isinstance(n_components, (int, np.integer)) or n_components < 1:
            raise ImitateError(f"n_components must be an integer >= 1; got {n_components}")
        if not reg_covar >= 0.0:
            raise ImitateError(f"reg_covar must be >= 0; got {reg_covar}")
        if not tol >= 0.0:
            raise ImitateError(f"tol must be >= 0; got {tol}")
        if max_iter < 1 or n_init < 1:
            raise ImitateError(f"max_iter and n_init must be >= 1; got {max_iter} and {n_init}")
        self.n_components = int(n_components)
        self.reg_covar = float(reg_covar)
        self.tol = float(tol)
        self.max_iter = int(max_iter)
        self.n_init = int(n_init)
        self.seed = seed

    @classmethod
    def from_parameters(
        cls, weights: ArrayLike, means: ArrayLike, covariances: ArrayLike, **kwargs
    ) -> GMM:
        """A fitted model with given parameters (e.g. loaded from ``model.npz``).

        Args:
            weights: Priors, shape ``(K,)``, ``>= 0``, summing to 1.
            means: Means, shape ``(K, D)``.
            covariances: Symmetric positive definite covariances, shape ``(K, D, D)``.
            **kwargs: Constructor arguments (used if the model is refitted).

        Raises:
            ImitateError: On inconsistent shapes, weights that are not a distribution or
                covariances that are not positive definite.
        """
        w = np.asarray(weights, dtype=float)
        mu = np.asarray(means, dtype=float)
        cov = np.asarray(covariances, dtype=float)
        if w.ndim != 1 or mu.ndim != 2 or mu.shape[0] != w.shape[0] or cov.shape != (
            w.shape[0], mu.shape[1], mu.shape[1]
        ):
            raise ImitateError(
                "expected weights (K,), means (K, D) and covariances (K, D, D); got shapes "
                f"{w.shape}, {mu.shape} and {cov.shape}"
            )
        if np.any(w < 0) or not np.isclose(w.sum(), 1.0, rtol=0, atol=1e-8):
            raise ImitateError(f"weights must be >= 0 and sum to 1; got sum {w.sum()}")
        if not (np.all(np.isfinite(mu)) and np.all(np.isfinite(cov))):
            raise ImitateError("means and covariances must be finite")
        if not np.allclose(cov, cov.transpose(0, 2, 1), rtol=1e-10, atol=1e-14):
            raise ImitateError("covariances must be symmetric")
        model = cls(w.shape[0], **kwargs)
        model._set_parameters(w, mu, cov)
        model.converged_ = True
        model.n_iter_ = 0
        model.lower_bound_ = -np.inf
        return model

    def _set_parameters(self, weights: np.ndarray, means: np.ndarray, cov: np.ndarray) -> None:
        self._prec_chol = np.zeros_like(cov)
        self._log_coef = np.empty_like(weights)
        if not _factor(weights, cov, self._prec_chol, self._log_coef):
            raise _not_positive_definite()
        self.precisions_ = self._prec_chol @ self._prec_chol.transpose(0, 2, 1)
        self.weights_ = weights
        self.means_ = means
        self.covariances_ = cov

    def initial_parameters(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The K-means initialisation that :meth:`fit` starts EM from.

        Args:
            X: Samples, shape ``(n_samples, n_dims)``.

        Returns:
            ``(weights, means, covariances)``, see
            :func:`kmeans_parameters`.
        """
        X = check_samples(X)
        labels = kmeans(X, self.n_components, n_init=self.n_init, seed=self.seed).labels
        return kmeans_parameters(X, labels, self.n_components, self.reg_covar)

    def fit(self, X: ArrayLike) -> GMM:
        """Fits the mixture by EM (eqs. 8-12) from the K-means initialisation.

        Args:
            X: Samples, shape ``(n_samples, n_dims)``, finite, ``n_samples >= n_components``.

        Returns:
            ``self``, fitted.

        Raises:
            ImitateError: On non-finite samples, more components than samples, or a covariance
                that ``reg_covar`` cannot make positive definite.
        """
        return self.fit_from(X, *self.initial_parameters(X))

    def fit_from(
        self, X: ArrayLike, weights: ArrayLike, means: ArrayLike, covariances: ArrayLike
    ) -> GMM:
        """Fits the mixture by EM from a given initialisation instead of K-means.

        Args:
            X: Samples, shape ``(n_samples, n_dims)``, finite.
            weights: Initial priors, shape ``(K,)``.
            means: Initial means, shape ``(K, D)``.
            covariances: Initial covariances, shape ``(K, D, D)``, positive definite.

        Returns:
            ``self``, fitted.
        """
        X = check_samples(X)
        init = GMM.from_parameters(weights, means, covariances)
        if init.means_.shape != (self.n_components, X.shape[1]):
            raise ImitateError(
                f"initial means must have shape ({self.n_components}, {X.shape[1]}); "
                f"got {init.means_.shape}"
            )
        weights, means, cov = (
            np.array(a, order="C") for a in (init.weights_, init.means_, init.covariances_)
        )
        n_iter, converged, lower_bound, ok = _em_loop(
            _sorted_transposed(X)[0], weights, means, cov, self.reg_covar, self.tol, self.max_iter
        )
        if not ok:
            raise _not_positive_definite()
        self.n_iter_, self.converged_, self.lower_bound_ = n_iter, converged, lower_bound
        self._set_parameters(weights, means, cov)
        return self

    def _check_fitted(self, X: ArrayLike) -> np.ndarray:
        if not hasattr(self, "means_"):
            raise ImitateError("this GMM is not fitted yet; call fit(X) or from_parameters first")
        X = check_samples(X)
        if X.shape[1] != self.means_.shape[1]:
            raise ImitateError(
                f"X has {X.shape[1]} dimensions but the model was fitted on "
                f"{self.means_.shape[1]}"
            )
        return X

    def _e_step(self, X: ArrayLike, with_resp: bool) -> tuple[np.ndarray, np.ndarray]:
        """``log p(x_i)`` (N,) and responsibilities (N, K) (or (0, K)) in the order of ``X``."""
        xt, order = _sorted_transposed(self._check_fitted(X))
        resp = np.empty((xt.shape[1] if with_resp else 0, self.n_components))
        log_norm = _e_step(
            xt, self.means_, self._prec_chol, self._log_coef, _LOG_FLUSH, resp,
            np.empty((0, 0)), np.empty((0, 0), dtype=bool),
        )
        log_norm[order] = log_norm.copy()
        if with_resp:
            resp[order] = resp.copy()
        return log_norm, resp

    def score_samples(self, X: ArrayLike) -> np.ndarray:
        """Log-likelihood ``log p(x_i)`` of each sample (eq. 3), shape ``(n_samples,)`` [nats]."""
        return self._e_step(X, with_resp=False)[0]

    def score(self, X: ArrayLike) -> float:
        """Mean log-likelihood per sample [nats]."""
        return float(self.score_samples(X).mean())

    def predict_proba(self, X: ArrayLike) -> np.ndarray:
        """Responsibilities ``p(k | x_i)`` (eq. 8), shape ``(n_samples, K)``, rows summing to 1."""
        return self._e_step(X, with_resp=True)[1]

    def bic(self, X: ArrayLike) -> float:
        """Bayesian information criterion (eq. 5 with the *total* log-likelihood, see
        :mod:`imitate.learning.bic`)."""
        log_norm = self.score_samples(X)
        return _bic(float(log_norm.sum()), self.n_components, self.means_.shape[1], log_norm.size)


