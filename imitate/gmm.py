r"""Gaussian mixture models with full covariances (paper eqs. 3-12): densities and EM.

Notation (the paper's): ``N`` samples ``x_i`` of dimension ``D`` (time plus task space), ``K``
components with priors ``pi_k``, means ``mu_k`` and covariances ``Sigma_k``.

Numerics follow scikit-learn's ``GaussianMixture(covariance_type="full")``, so that both reach the
same log-likelihood from the same start: densities in log space through the Cholesky factor of
each covariance, responsibilities normalised by log-sum-exp (terms below ``exp(-50)`` of the
largest flushed to zero), and ``reg_covar`` added to the diagonal of every covariance, which also
keeps a cluster of identical samples usable (covariance ``reg_covar * I``). The density and EM
loops are compiled (numba) and skip, per block of samples sorted by time, the components whose
responsibilities a lower bound of the Mahalanobis distance already puts below the flush threshold.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import ArrayLike

from imitate._validation import check_samples
from imitate.errors import ImitateError
from imitate.kmeans import _EPS_COUNTS, kmeans, kmeans_parameters

__all__ = ["GMM", "exp_flushed", "n_parameters"]

_LOG_2PI = np.log(2.0 * np.pi)
# Responsibilities below exp(-50) ~ 2e-22 of a sample's largest are flushed to 0: over all N
# samples they add less than N * 2e-22 to a soft count (below round-off for any component that
# holds a hundredth of a sample), and skipping them lets most components go unevaluated.
_LOG_FLUSH = -50.0


def n_parameters(n_components: int, n_dims: int) -> int:
    """Number of free parameters ``P`` of a full-covariance GMM (eq. 7)."""
    return (n_components - 1) + n_components * (n_dims + n_dims * (n_dims + 1) // 2)


def _bic(log_likelihood: float, n_components: int, n_dims: int, n_samples: int) -> float:
    """BIC from the total log-likelihood [nats] (eq. 5, see :mod:`imitate.bic`)."""
    return -2.0 * log_likelihood + n_parameters(n_components, n_dims) * np.log(n_samples)


@numba.njit(cache=True)
def _factor(
    weights: np.ndarray, covariances: np.ndarray, prec_chol: np.ndarray, log_coef: np.ndarray
) -> bool:
    """Cholesky factors of the precisions and log normalisers of all components, in place.

    Args:
        weights: Priors ``pi_k``, shape ``(K,)``.
        covariances: ``Sigma_k``, shape ``(K, D, D)``, symmetric.
        prec_chol: Output, shape ``(K, D, D)``: ``U_k = L_k^{-T}`` (upper triangle, zeros below)
            with ``Sigma_k = L_k L_k^T``, so that ``Sigma_k^{-1} = U_k U_k^T`` (scikit-learn's
            ``precisions_cholesky_``).
        log_coef: Output, shape ``(K,)``: ``log pi_k - log |L_k| - D/2 log(2 pi)``.

    Returns:
        ``False`` if a covariance is not positive definite (outputs then undefined).
    """
    n_components, d, _ = covariances.shape
    chol = np.zeros((d, d))
    for k in range(n_components):
        log_det = 0.0
        for j in range(d):
            s = covariances[k, j, j]
            for e in range(j):
                s -= chol[j, e] * chol[j, e]
            if not s > 0.0:
                return False
            chol[j, j] = math.sqrt(s)
            log_det += math.log(chol[j, j])
            for r in range(j + 1, d):
                t = covariances[k, r, j]
                for e in range(j):
                    t -= chol[r, e] * chol[j, e]
                chol[r, j] = t / chol[j, j]
        for j in range(d):
            prec_chol[k, j, j] = 1.0 / chol[j, j]
            for r in range(j + 1, d):
                t = 0.0
                for e in range(j, r):
                    t -= chol[r, e] * prec_chol[k, j, e]
                prec_chol[k, j, r] = t / chol[r, r]
        log_coef[k] = math.log(weights[k]) - log_det - 0.5 * d * _LOG_2PI
    return True


@numba.njit(cache=True)
def _block_differences(
    xt: np.ndarray, start: int, stop: int, mean: np.ndarray, diff: np.ndarray
) -> None:
    """``diff[e, i] = xt[e, start + i] - mean[e]`` for one block, ``diff`` of shape ``(D, B)``."""
    for e in range(xt.shape[0]):
        source = xt[e, start:stop]
        target = diff[e]
        mu = mean[e]
        for i in range(stop - start):
            target[i] = source[i] - mu


@numba.njit(cache=True, fastmath={"reassoc", "contract"})
def _accumulate_moments(
    resp: np.ndarray, diff: np.ndarray, size: int, k: int, counts: np.ndarray,
    first: np.ndarray, second: np.ndarray,
) -> None:
    """Adds one block's weighted moments to component ``k``: ``counts[k] += sum_i r_i``,
    ``first[k] += sum_i r_i d_i`` and the lower triangle of ``second[k] += sum_i r_i d_i d_i^T``.

    ``resp`` (B,) holds ``r_i``, ``diff`` (D, B) the differences ``d_i``; only the first ``size``
    samples count. The sums are reassociated (vectorised); all terms are finite.
    """
    d = diff.shape[0]
    total = 0.0
    for i in range(size):
        total += resp[i]
    counts[k] += total
    weighted = np.empty(size)
    for e in range(d):
        diff_e = diff[e]
        for i in range(size):
            weighted[i] = resp[i] * diff_e[i]
        total = 0.0
        for i in range(size):
            total += weighted[i]
        first[k, e] += total
        for f in range(e + 1):
            diff_f = diff[f]
            total = 0.0
            for i in range(size):
                total += weighted[i] * diff_f[i]
            second[k, e, f] += total


@numba.njit(cache=True)
def _block_log_densities(
    xt: np.ndarray, start: int, stop: int, means: np.ndarray, prec_chol: np.ndarray,
    log_coef: np.ndarray, threshold: float, terms: np.ndarray, diff: np.ndarray,
    partial: np.ndarray, tops: np.ndarray,
) -> None:
    """Weighted log-densities ``log pi_k N(x_i; mu_k, Sigma_k)`` of one block of samples.

    The samples are sorted by their first dimension, so the block spans a short interval of it;
    ``(x_0 - mu_k0)^2 / Sigma_k00``, evaluated at the interval's point nearest ``mu_k0``, is a
    lower bound of every sample's Mahalanobis distance to component ``k``. Components are visited
    from the largest resulting upper bound down; once a component's bound is more than
    ``-threshold`` below the smallest best-so-far term of the block, it and all following ones
    are left out (``-inf``): their responsibilities would be below ``exp(threshold)``. Each
    evaluated component costs ``D (D + 3) / 2`` multiply-adds per sample, in loops over the
    samples (vectorised).

    Args:
        xt: Sorted samples, transposed, shape ``(D, N)``.
        start, stop: The block, samples ``start..stop-1``.
        means, prec_chol, log_coef: The mixture, see :func:`_factor`.
        threshold: Log-ratio to a sample's best term below which terms may be dropped (< 0).
        terms: Output, shape ``(K, >= stop - start)``.
        diff, partial, tops: Scratch, shapes ``(D, B)``, ``(B,)``, ``(B,)`` with
            ``B >= stop - start``.
    """
    n_components, d = means.shape
    size = stop - start
    lo, hi = xt[0, start], xt[0, stop - 1]
    bounds = np.empty(n_components)
    for k in range(n_components):
        gap = max(lo - means[k, 0], means[k, 0] - hi, 0.0) * prec_chol[k, 0, 0]
        bounds[k] = log_coef[k] - 0.5 * gap * gap
    order = np.argsort(-bounds)
    tops[:size] = -np.inf
    floor = -np.inf  # smallest best-so-far term over the block
    for rank in range(n_components):
        k = order[rank]
        if bounds[k] - floor < threshold:
            for rest in range(rank, n_components):
                terms[order[rest], :size] = -np.inf
            return
        _block_differences(xt, start, stop, means[k], diff)
        row = terms[k]
        for i in range(size):
            row[i] = log_coef[k]
        for j in range(d):
            for i in range(size):
                partial[i] = 0.0
            for e in range(j + 1):
                u = prec_chol[k, e, j]
                diff_e = diff[e]
                for i in range(size):
                    partial[i] += u * diff_e[i]
            for i in range(size):
                row[i] -= 0.5 * partial[i] * partial[i]
        floor = np.inf
        for i in range(size):
            tops[i] = max(tops[i], row[i])
            floor = min(floor, tops[i])


@numba.njit(cache=True)
def _log_norm(terms: np.ndarray, i: int, threshold: float) -> float:
    """``log sum_k exp(terms[k, i])`` by the log-sum-exp trick, dropping terms below
    ``exp(threshold)`` of the largest."""
    top = -np.inf
    for k in range(terms.shape[0]):
        top = max(top, terms[k, i])
    total = 0.0
    for k in range(terms.shape[0]):
        if terms[k, i] - top >= threshold:
            total += math.exp(terms[k, i] - top)
    return top + math.log(total)


_BLOCK = 128  # samples per block: the scratch arrays stay in the L1 cache


@numba.njit(cache=True)
def _e_step(
    xt: np.ndarray, means: np.ndarray, prec_chol: np.ndarray, log_coef: np.ndarray,
    threshold: float, resp: np.ndarray,
) -> np.ndarray:
    """Per-sample log-likelihood ``log p(x_i)`` (eq. 3), shape ``(N,)``, of sorted samples.

    Args:
        xt: Samples sorted by their first dimension, transposed, shape ``(D, N)``.
        means, prec_chol, log_coef: The mixture, see :func:`_factor`.
        threshold: Terms below ``exp(threshold)`` of a sample's largest are dropped (< 0).
        resp: Output, shape ``(N, K)``, or ``(0, K)`` to skip it: responsibilities ``p(k | x_i)``
            (eq. 8), exactly 0 where below ``exp(threshold)``.
    """
    d, n = xt.shape
    n_components = means.shape[0]
    terms = np.empty((n_components, _BLOCK))
    diff = np.empty((d, _BLOCK))
    partial = np.empty(_BLOCK)
    tops = np.empty(_BLOCK)
    log_norm = np.empty(n)
    for start in range(0, n, _BLOCK):
        stop = min(start + _BLOCK, n)
        _block_log_densities(xt, start, stop, means, prec_chol, log_coef, threshold, terms,
                             diff, partial, tops)
        for i in range(stop - start):
            log_norm[start + i] = _log_norm(terms, i, threshold)
            if resp.shape[0] == n:
                for k in range(n_components):
                    log_resp = terms[k, i] - log_norm[start + i]
                    resp[start + i, k] = math.exp(log_resp) if log_resp >= threshold else 0.0
    return log_norm


@numba.njit(cache=True)
def _em_loop(
    xt: np.ndarray, weights: np.ndarray, means: np.ndarray, covariances: np.ndarray,
    reg_covar: float, tol: float, max_iter: int,
) -> tuple[int, bool, float, bool]:
    """EM (eqs. 8-12) in place on ``weights`` (K,), ``means`` (K, D), ``covariances`` (K, D, D).

    Each iteration is one pass over the blocks of sorted samples ``xt`` (D, N): the E-step of a
    block (responsibilities below ``exp(-50)`` flushed to 0) is accumulated at once into the
    soft counts and the first and second moments about the current means; the M-step then
    shifts the means and subtracts the shift from the second moments. Stops when the mean
    log-likelihood per sample (before the M-step) changes by less than ``tol``.

    Returns:
        ``(n_iter, converged, lower_bound, positive_definite)``; ``positive_definite`` is
        ``False`` when a covariance lost definiteness (parameters then undefined).
    """
    d, n = xt.shape
    n_components = means.shape[0]
    prec_chol = np.zeros((n_components, d, d))
    log_coef = np.empty(n_components)
    if not _factor(weights, covariances, prec_chol, log_coef):
        return 0, False, -np.inf, False
    counts = np.empty(n_components)
    first = np.empty((n_components, d))
    second = np.empty((n_components, d, d))
    terms = np.empty((n_components, _BLOCK))
    diff = np.empty((d, _BLOCK))
    partial = np.empty(_BLOCK)
    tops = np.empty(_BLOCK)
    resp = np.empty(_BLOCK)
    lower_bound = -np.inf
    n_iter = 0
    while n_iter < max_iter:
        n_iter += 1
        previous = lower_bound
        counts[:] = 0.0
        first[:] = 0.0
        second[:] = 0.0
        total = 0.0
        for start in range(0, n, _BLOCK):
            stop = min(start + _BLOCK, n)
            _block_log_densities(xt, start, stop, means, prec_chol, log_coef, _LOG_FLUSH,
                                 terms, diff, partial, tops)
            size = stop - start
            for i in range(size):  # log p(x_i), kept in tops
                tops[i] = _log_norm(terms, i, _LOG_FLUSH)
                total += tops[i]
            for k in range(n_components):
                row = terms[k]
                used = False
                for i in range(size):
                    log_resp = row[i] - tops[i]
                    resp[i] = math.exp(log_resp) if log_resp >= _LOG_FLUSH else 0.0
                    used = used or resp[i] > 0.0
                if used:
                    _block_differences(xt, start, stop, means[k], diff)
                    _accumulate_moments(resp, diff, size, k, counts, first, second)
        counts += _EPS_COUNTS  # e_k, eq. 9
        total_counts = counts.sum()
        for k in range(n_components):
            weights[k] = counts[k] / total_counts  # eq. 10
            for e in range(d):
                first[k, e] /= counts[k]
            for e in range(d):
                for f in range(e + 1):  # eq. 12 about the new mean (eq. 11)
                    c = second[k, e, f] / counts[k] - first[k, e] * first[k, f]
                    covariances[k, e, f] = c
                    covariances[k, f, e] = c
                covariances[k, e, e] += reg_covar
                means[k, e] += first[k, e]
        lower_bound = total / n
        if not _factor(weights, covariances, prec_chol, log_coef):
            return n_iter, False, lower_bound, False
        if abs(lower_bound - previous) < tol:
            return n_iter, True, lower_bound, True
    return n_iter, False, lower_bound, True


def _sorted_transposed(X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Samples sorted by their first dimension and transposed, ``(D, N)``, and the order."""
    order = np.argsort(X[:, 0], kind="stable")
    return np.ascontiguousarray(X[order].T), order


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
        n_init: Number of K-means starts for the initialisation (see :func:`imitate.kmeans.kmeans`).
        seed: Seed of the K-means starts (see :func:`imitate.kmeans.kmeans`).

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
        >>> np.round(np.sort(gmm.means_[:, 0]), 1).tolist()
        [0.0, 3.0]
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
            ``(weights, means, covariances)``, see :func:`imitate.kmeans.kmeans_parameters`.
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
        log_norm = _e_step(xt, self.means_, self._prec_chol, self._log_coef, _LOG_FLUSH, resp)
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
        :mod:`imitate.bic`)."""
        log_norm = self.score_samples(X)
        return _bic(float(log_norm.sum()), self.n_components, self.means_.shape[1], log_norm.size)


