r"""Gaussian mixture models (paper eqs. 3-12): K-means initialisation, EM, BIC model selection.

Notation (the paper's): ``N`` samples ``x_i`` of dimension ``D`` (time plus task space), ``K``
components with priors ``pi_k``, means ``mu_k`` and covariances ``Sigma_k``.

Numerics follow scikit-learn's ``GaussianMixture(covariance_type="full")`` so that both reach the
same log-likelihood from the same start: densities are evaluated in log space through the
Cholesky factor of each precision matrix (no explicit inverse of ``Sigma_k``), responsibilities are
normalised with the log-sum-exp trick, and ``reg_covar`` is added to the diagonal of every
covariance. The regularisation is also what keeps duplicated points (a cluster of identical
samples has a zero covariance) usable: such a component gets the covariance ``reg_covar * I``.

Model selection (eqs. 5-7). The paper's eq. 6 divides the log-likelihood by ``N``; combined with
eq. 5's penalty ``P ln N`` that makes the penalty dominate and always selects ``K = 1``. We use
the total log-likelihood, the standard BIC (``BIC = -2 sum_i log p(x_i) + P ln N``, as
scikit-learn's ``GaussianMixture.bic``), with ``P`` from eq. 7.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from imitate.errors import ImitateError

__all__ = [
    "GMM",
    "KMeansResult",
    "kmeans",
    "kmeans_parameters",
    "n_parameters",
    "select_components",
]

_LOG_2PI = np.log(2.0 * np.pi)
# scikit-learn adds this to the soft counts so that an empty component does not divide by zero.
_EPS_COUNTS = 10.0 * np.finfo(float).eps
# exp() of anything below this is flushed to 0: subnormal numbers (below ~1e-308, reached by
# exp(-708)) make the following matrix products about 100x slower and carry no information.
_LOG_FLUSH = -460.0  # exp(-460) ~ 1e-200
# K-means defaults (scikit-learn's) used for the initialisation of EM and for the BIC sweep.
_KMEANS_MAX_ITER = 100
_KMEANS_TOL = 1e-4


def _check_data(X: ArrayLike, name: str = "X") -> np.ndarray:
    """Validates samples as a finite float array of shape ``(n_samples, n_dims)``."""
    arr = np.asarray(X, dtype=float)
    if arr.ndim != 2 or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ImitateError(
            f"{name} must be a non-empty 2-D array of shape (n_samples, n_dims); "
            f"got shape {np.shape(X)}"
        )
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ImitateError(
            f"{name} contains a non-finite value ({arr[tuple(bad)]}) at sample {bad[0]}, "
            f"dimension {bad[1]}"
        )
    return arr


def _check_n_components(n_components: int, n_samples: int) -> None:
    if not isinstance(n_components, (int, np.integer)) or n_components < 1:
        raise ImitateError(f"the number of components must be an integer >= 1; got {n_components}")
    if n_components > n_samples:
        raise ImitateError(
            f"more components ({n_components}) than samples ({n_samples}); use at most "
            f"{n_samples} components or provide more data"
        )


def n_parameters(n_components: int, n_dims: int) -> int:
    """Number of free parameters ``P`` of a full-covariance GMM (eq. 7)."""
    return (n_components - 1) + n_components * (n_dims + n_dims * (n_dims + 1) // 2)


# ---------------------------------------------------------------------------------------------
# Data in centred form, shared by K-means, EM and the BIC sweep


@dataclass(frozen=True)
class _Data:
    """Samples centred on their mean, with their flattened outer products.

    Densities and covariances are computed from ``outer`` with one matrix product for all
    components (``(x-mu)^T P (x-mu) = <x x^T, P> - 2 mu^T P x + mu^T P mu``); centring keeps the
    cancellation in that expansion at round-off level.
    """

    x: np.ndarray  # (N, D), centred
    centre: np.ndarray  # (D,)
    outer: np.ndarray  # (N, D * D)
    x_sq: np.ndarray  # (N,), squared norms of the centred samples
    x_lifted: np.ndarray  # (N, D + 1), the centred samples with a column of ones

    @classmethod
    def of(cls, X: np.ndarray) -> _Data:
        centre = X.mean(axis=0)
        x = X - centre
        outer = (x[:, :, None] * x[:, None, :]).reshape(x.shape[0], -1)
        x_sq = np.einsum("ij,ij->i", x, x)
        x_lifted = np.hstack((x, np.ones((x.shape[0], 1))))
        return cls(x=x, centre=centre, outer=outer, x_sq=x_sq, x_lifted=x_lifted)


# ---------------------------------------------------------------------------------------------
# K-means


@dataclass(frozen=True)
class KMeansResult:
    """Outcome of :func:`kmeans`.

    Attributes:
        centers: Cluster centres, shape ``(n_clusters, n_dims)``.
        labels: Cluster of each sample, shape ``(n_samples,)``, values in ``[0, n_clusters)``.
        inertia: Sum of squared distances of the samples to their centres.
    """

    centers: np.ndarray
    labels: np.ndarray
    inertia: float


def _start_generator(seed: int, start: int) -> np.random.Generator:
    """Generator of one K-means start; independent of the number of clusters, so the first K
    centres of a longer k-means++ sequence are exactly the seeding of a K-cluster run."""
    return np.random.default_rng([seed, start])


def _kmeans_plusplus(data: _Data, n_clusters: int, rng: np.random.Generator) -> np.ndarray:
    """k-means++ seeding: each new centre is drawn with probability ~ squared distance.

    Returns:
        Indices of the chosen samples, shape ``(n_clusters,)``, in the order drawn.
    """
    x, x_sq = data.x, data.x_sq
    n_samples = x.shape[0]
    chosen = np.empty(n_clusters, dtype=np.intp)
    chosen[0] = rng.integers(n_samples)
    closest = np.maximum(x_sq - 2.0 * (x @ x[chosen[0]]) + x_sq[chosen[0]], 0.0)
    for c in range(1, n_clusters):
        cumulative = np.cumsum(closest)
        if cumulative[-1] > 0.0:
            idx = min(int(np.searchsorted(cumulative, rng.uniform(0.0, cumulative[-1]))),
                      n_samples - 1)
        else:  # fewer distinct points than clusters: any point will do
            idx = int(rng.integers(n_samples))
        chosen[c] = idx
        np.minimum(closest, np.maximum(x_sq - 2.0 * (x @ x[idx]) + x_sq[idx], 0.0), out=closest)
    return chosen


def _sq_distances_shifted(data: _Data, centers: np.ndarray) -> np.ndarray:
    """``|x_i - c_k|^2 - |x_i|^2`` for all samples and centres with one matrix product."""
    lifted = np.vstack((-2.0 * centers.T, np.einsum("kd,kd->k", centers, centers)))
    return data.x_lifted @ lifted


def _lloyd(
    data: _Data, centers: np.ndarray, max_iter: int, tol: float
) -> tuple[np.ndarray, np.ndarray, float]:
    """Lloyd iterations until the labels stop changing or the centres move less than ``tol``.

    Cluster sums are updated incrementally from the samples that changed cluster. Empty clusters
    are moved to the samples farthest from their centres.

    Returns:
        ``(centers, labels, inertia)``.
    """
    x = data.x
    n_samples, n_clusters = x.shape[0], centers.shape[0]
    labels = np.full(n_samples, -1)
    sums = np.zeros_like(centers)
    counts = np.zeros(n_clusters, dtype=np.intp)
    for _ in range(max_iter):
        d2 = _sq_distances_shifted(data, centers)
        new_labels = np.argmin(d2, axis=1)
        new_counts = np.bincount(new_labels, minlength=n_clusters)
        if not new_counts.all():
            empty = np.flatnonzero(new_counts == 0)
            far = np.argsort(np.take_along_axis(d2, new_labels[:, None], 1)[:, 0] + data.x_sq)
            new_labels[far[::-1][: empty.size]] = empty
            new_counts = np.bincount(new_labels, minlength=n_clusters)
        moved = np.flatnonzero(new_labels != labels)
        if moved.size == 0:
            break
        if labels[0] < 0:
            sums = _one_hot(new_labels, n_clusters).T @ x
        else:
            np.add.at(sums, new_labels[moved], x[moved])
            np.subtract.at(sums, labels[moved], x[moved])
        labels, counts = new_labels, new_counts
        new_centers = sums / counts[:, None]
        shift = float(np.sum((new_centers - centers) ** 2))
        centers = new_centers
        if shift <= tol:
            break
    centers = (_one_hot(labels, n_clusters).T @ x) / counts[:, None]  # exact, no drift
    diff = x - centers[labels]
    return centers, labels, float(np.einsum("ij,ij->", diff, diff))


def _kmeans_starts(
    data: _Data, n_clusters: Sequence[int], n_init: int, max_iter: int, tol: float, seed: int
) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Best of ``n_init`` K-means runs for every K in ``n_clusters`` (one seeding per start)."""
    tol_abs = tol * float(np.mean(data.x_sq)) / data.x.shape[1]  # tol relative to mean variance
    best: list[tuple[np.ndarray, np.ndarray, float] | None] = [None] * len(n_clusters)
    for start in range(n_init):
        seeds = _kmeans_plusplus(data, max(n_clusters), _start_generator(seed, start))
        for n, k in enumerate(n_clusters):
            run = _lloyd(data, data.x[seeds[:k]], max_iter, tol_abs)
            if best[n] is None or run[2] < best[n][2]:
                best[n] = run
    return best


def kmeans(
    X: ArrayLike,
    n_clusters: int,
    *,
    n_init: int = 3,
    max_iter: int = _KMEANS_MAX_ITER,
    tol: float = _KMEANS_TOL,
    seed: int = 0,
) -> KMeansResult:
    """K-means clustering with k-means++ seeding and several seeded starts.

    A single K-means run can stall in a poor local optimum, which makes a BIC curve built from
    K-means alone jagged; the best of ``n_init`` starts (lowest inertia) guards against that.

    Args:
        X: Samples, shape ``(n_samples, n_dims)``, finite.
        n_clusters: Number of clusters, ``1 <= n_clusters <= n_samples``.
        n_init: Number of k-means++ starts, ``>= 1``.
        max_iter: Maximum number of Lloyd iterations per start, ``>= 1``.
        tol: Stop when the summed squared centre shift falls below ``tol`` times the mean
            per-dimension variance of ``X`` (scikit-learn's convention).
        seed: Seed of the starts; start ``i`` draws from ``default_rng([seed, i])``.

    Returns:
        The best :class:`KMeansResult` of all starts.

    Raises:
        ImitateError: On non-finite samples or a bad ``n_clusters``, ``n_init`` or ``max_iter``.
    """
    X = _check_data(X)
    _check_n_components(n_clusters, X.shape[0])
    if n_init < 1 or max_iter < 1:
        raise ImitateError(f"n_init and max_iter must be >= 1; got {n_init} and {max_iter}")
    data = _Data.of(X)
    centers, labels, inertia = _kmeans_starts(data, [n_clusters], n_init, max_iter, tol, seed)[0]
    return KMeansResult(centers=centers + data.centre, labels=labels, inertia=inertia)


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
    data = _Data.of(_check_data(X))
    weights, means, cov = _m_step(data, _one_hot(np.asarray(labels), n_components), reg_covar)
    return weights, means + data.centre, cov


def _one_hot(labels: np.ndarray, n_components: int) -> np.ndarray:
    return (labels[:, None] == np.arange(n_components)).astype(float)


# ---------------------------------------------------------------------------------------------
# Gaussian densities and the two EM steps


def _precisions(covariances: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Precision matrices through Cholesky factors, and ``-1/2 log |Sigma_k|``.

    Returns:
        ``(precisions, half_log_det)`` of shapes ``(K, D, D)`` and ``(K,)``.
    """
    try:
        lower = np.linalg.cholesky(covariances)
    except np.linalg.LinAlgError:
        raise ImitateError(
            "a component covariance is not positive definite (singular data such as duplicated "
            "points or a constant dimension); increase reg_covar, use fewer components or "
            "rescale the data"
        ) from None
    inv_lower = np.linalg.inv(lower)
    precisions = inv_lower.transpose(0, 2, 1) @ inv_lower
    return precisions, -np.log(np.diagonal(lower, axis1=1, axis2=2)).sum(axis=1)


def _log_gaussian(
    data: _Data, means: np.ndarray, precisions: np.ndarray, half_log_det: np.ndarray
) -> np.ndarray:
    """``log N(x_i; mu_k, Sigma_k)`` (eq. 4) for all samples and (centred) means, ``(N, K)``."""
    n_components, n_dims = means.shape
    p_mu = np.einsum("kde,ke->kd", precisions, means)
    maha = data.outer @ precisions.reshape(n_components, n_dims * n_dims).T
    maha -= 2.0 * (data.x @ p_mu.T)
    maha += np.einsum("kd,kd->k", means, p_mu)
    np.maximum(maha, 0.0, out=maha)
    maha *= -0.5
    maha += half_log_det - 0.5 * n_dims * _LOG_2PI
    return maha


def _exp_flushed(a: np.ndarray) -> np.ndarray:
    """``exp(a)`` with entries where ``a < -460`` set to exactly 0 (no subnormal numbers)."""
    return np.exp(a, out=np.zeros_like(a), where=a >= _LOG_FLUSH)


def _e_step(
    data: _Data, weights: np.ndarray, means: np.ndarray, precisions: np.ndarray,
    half_log_det: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Responsibilities (eq. 8) in log space, for centred means.

    Returns:
        ``(log_norm, log_resp)``: per-sample log-likelihood ``log p(x_i)`` (eq. 3), shape ``(N,)``,
        and ``log p(k | x_i)``, shape ``(N, K)``.
    """
    weighted = _log_gaussian(data, means, precisions, half_log_det)
    weighted += np.log(weights)
    top = weighted.max(axis=1, keepdims=True)
    log_norm = np.log(_exp_flushed(weighted - top).sum(axis=1)) + top[:, 0]
    weighted -= log_norm[:, None]
    return log_norm, weighted


def _m_step(
    data: _Data, resp: np.ndarray, reg_covar: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Priors, centred means and regularised covariances from responsibilities (eqs. 9-12)."""
    n_dims = data.x.shape[1]
    counts = resp.sum(axis=0) + _EPS_COUNTS  # e_k, eq. 9
    means = (resp.T @ data.x) / counts[:, None]  # eq. 11
    second = (resp.T @ data.outer).reshape(-1, n_dims, n_dims) / counts[:, None, None]
    covariances = second - means[:, :, None] * means[:, None, :]  # eq. 12
    covariances[:, np.arange(n_dims), np.arange(n_dims)] += reg_covar
    weights = counts / counts.sum()  # eq. 10
    return weights, means, covariances


# ---------------------------------------------------------------------------------------------
# The model


class GMM:
    """Gaussian mixture model with full covariances, trained by EM from a K-means start.

    Args:
        n_components: Number of components ``K >= 1``.
        reg_covar: Added to the diagonal of every covariance (in the squared units of the data),
            ``>= 0``; keeps components of duplicated or collinear points non-singular.
        tol: EM stops when the mean log-likelihood per sample changes by less than this [nats].
        max_iter: Maximum number of EM iterations, ``>= 1``.
        n_init: Number of k-means++ starts for the initialisation (lowest inertia wins).
        seed: Seed of the K-means starts (see :func:`kmeans`).

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
        self.precisions_, self._half_log_det = _precisions(cov)
        self.weights_ = weights
        self.means_ = means
        self.covariances_ = cov

    def initial_parameters(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The K-means initialisation that :meth:`fit` starts EM from.

        Args:
            X: Samples, shape ``(n_samples, n_dims)``.

        Returns:
            ``(weights, means, covariances)``, see :func:`kmeans_parameters`.
        """
        X = _check_data(X)
        _check_n_components(self.n_components, X.shape[0])
        clusters = kmeans(X, self.n_components, n_init=self.n_init, seed=self.seed)
        return kmeans_parameters(X, clusters.labels, self.n_components, self.reg_covar)

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
        X = _check_data(X)
        _check_n_components(self.n_components, X.shape[0])
        data = _Data.of(X)
        _, labels, _ = _kmeans_starts(
            data, [self.n_components], self.n_init, _KMEANS_MAX_ITER, _KMEANS_TOL, self.seed
        )[0]
        self._em(data, *_m_step(data, _one_hot(labels, self.n_components), self.reg_covar))
        return self

    def _em(self, data: _Data, weights: np.ndarray, means: np.ndarray, cov: np.ndarray) -> None:
        """EM from given parameters (means centred on ``data.centre``)."""
        precisions, half_log_det = _precisions(cov)
        lower_bound = -np.inf
        self.converged_ = False
        self.n_iter_ = 0
        while self.n_iter_ < self.max_iter:
            self.n_iter_ += 1
            previous = lower_bound
            log_norm, log_resp = _e_step(data, weights, means, precisions, half_log_det)
            weights, means, cov = _m_step(data, _exp_flushed(log_resp), self.reg_covar)
            precisions, half_log_det = _precisions(cov)
            lower_bound = float(log_norm.mean())
            if abs(lower_bound - previous) < self.tol:
                self.converged_ = True
                break
        self.lower_bound_ = lower_bound
        self._set_parameters(weights, means + data.centre, cov)

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
        X = _check_data(X)
        init = GMM.from_parameters(weights, means, covariances)
        if init.means_.shape != (self.n_components, X.shape[1]):
            raise ImitateError(
                f"initial means must have shape ({self.n_components}, {X.shape[1]}); "
                f"got {init.means_.shape}"
            )
        data = _Data.of(X)
        self._em(data, init.weights_, init.means_ - data.centre, init.covariances_)
        return self

    def _check_fitted(self, X: ArrayLike) -> _Data:
        if not hasattr(self, "means_"):
            raise ImitateError("this GMM is not fitted yet; call fit(X) or from_parameters first")
        X = _check_data(X)
        if X.shape[1] != self.means_.shape[1]:
            raise ImitateError(
                f"X has {X.shape[1]} dimensions but the model was fitted on "
                f"{self.means_.shape[1]}"
            )
        return _Data.of(X)

    def _e_step(self, X: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        data = self._check_fitted(X)
        return _e_step(data, self.weights_, self.means_ - data.centre, self.precisions_,
                       self._half_log_det)

    def score_samples(self, X: ArrayLike) -> np.ndarray:
        """Log-likelihood ``log p(x_i)`` of each sample (eq. 3), shape ``(n_samples,)`` [nats]."""
        return self._e_step(X)[0]

    def score(self, X: ArrayLike) -> float:
        """Mean log-likelihood per sample [nats]."""
        return float(self.score_samples(X).mean())

    def predict_proba(self, X: ArrayLike) -> np.ndarray:
        """Responsibilities ``p(k | x_i)`` (eq. 8), shape ``(n_samples, K)``, rows summing to 1."""
        return _exp_flushed(self._e_step(X)[1])

    def bic(self, X: ArrayLike) -> float:
        """Bayesian information criterion (eq. 5 with the *total* log-likelihood, see module)."""
        log_norm = self.score_samples(X)
        return _bic(float(log_norm.sum()), self.n_components, self.means_.shape[1], log_norm.size)


# ---------------------------------------------------------------------------------------------
# Choosing K


def _bic(log_likelihood: float, n_components: int, n_dims: int, n_samples: int) -> float:
    return -2.0 * log_likelihood + n_parameters(n_components, n_dims) * np.log(n_samples)


_BIC_METHODS = ("fast", "full")


def select_components(
    X: ArrayLike,
    k_max: int = 30,
    method: str = "fast",
    seed: int = 0,
    *,
    reg_covar: float = 1e-6,
    n_init: int = 3,
    tol: float = 1e-3,
    max_iter: int = 100,
) -> tuple[int, np.ndarray]:
    """Chooses the number of components ``K`` by the smallest BIC over ``K = 1..k_max``.

    ``"fast"`` is the paper's heuristic (section IV-B.1): K-means only, priors, means and
    covariances taken from the clusters, no EM. ``"full"`` trains a GMM by EM for every ``K``
    from that same K-means start (so ``"full"`` is never below ``"fast"`` in likelihood). The
    fast heuristic tends to choose more components than the full one (Fig. 5).

    Args:
        X: Samples, shape ``(n_samples, n_dims)``, finite.
        k_max: Largest ``K`` tried, ``1 <= k_max <= n_samples``.
        method: ``"fast"`` or ``"full"``.
        seed: Seed of the K-means starts (see :func:`kmeans`).
        reg_covar: Covariance regularisation, see :class:`GMM`.
        n_init: Number of k-means++ starts per ``K``.
        tol: EM tolerance for ``"full"``, see :class:`GMM`.
        max_iter: EM iteration limit for ``"full"``.

    Returns:
        ``(k, bic_curve)``: the chosen ``K`` and the BIC for ``K = 1..k_max``, shape ``(k_max,)``.

    Raises:
        ImitateError: On a bad method, ``k_max`` out of range or non-finite samples.
    """
    if method not in _BIC_METHODS:
        raise ImitateError(f"method must be one of {_BIC_METHODS}; got {method!r}")
    X = _check_data(X)
    _check_n_components(k_max, X.shape[0])
    data = _Data.of(X)
    n_samples, n_dims = X.shape
    ks = list(range(1, k_max + 1))
    curve = np.empty(k_max)
    starts = _kmeans_starts(data, ks, n_init, _KMEANS_MAX_ITER, _KMEANS_TOL, seed)
    for n, (_, labels, _) in enumerate(starts):
        weights, means, cov = _m_step(data, _one_hot(labels, ks[n]), reg_covar)
        if method == "fast":
            log_norm, _ = _e_step(data, weights, means, *_precisions(cov))
            log_likelihood = float(log_norm.sum())
        else:
            model = GMM(ks[n], reg_covar=reg_covar, tol=tol, max_iter=max_iter)
            model._em(data, weights, means, cov)
            log_likelihood = float(model.score_samples(X).sum())
        curve[n] = _bic(log_likelihood, ks[n], n_dims, n_samples)
    return int(np.argmin(curve)) + 1, curve
