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

Speed. K-means runs as compiled loops (numba): Lloyd's algorithm with Hamerly's distance bounds
(exactly Lloyd's iterates, but most samples are not measured again once centres move little),
and the clusterings for ``K = 1, 2, ...`` grow incrementally, each from the previous optimum plus
one k-means++ centre, in ``n_init`` independent chains. The fast BIC sweep computes the cluster
moments in one pass and the log-likelihood from one matrix product per ``K``, without
responsibilities. The first call of a process compiles the loops (about 10 s) or loads them from
numba's on-disk cache (about 0.5 s).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
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
# exp(-38) ~ 3e-17 < 2^-53 / 2: negligible next to a term exp(0) = 1 (see _sum_log_mixture).
_LOG_NEGLIGIBLE = -38.0
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

    @classmethod
    def of(cls, X: np.ndarray) -> _Data:
        centre = X.mean(axis=0)
        x = X - centre
        outer = (x[:, :, None] * x[:, None, :]).reshape(x.shape[0], -1)
        x_sq = np.einsum("ij,ij->i", x, x)
        return cls(x=x, centre=centre, outer=outer, x_sq=x_sq)


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
    """Generator of one K-means start (one chain of K = 1, 2, ... clusterings)."""
    return np.random.default_rng([seed, start])


@numba.njit(cache=True)
def _distance(x_i: np.ndarray, center: np.ndarray) -> float:
    """Euclidean distance between one sample and one centre, both of shape ``(D,)``."""
    total = 0.0
    for e in range(x_i.shape[0]):
        diff = x_i[e] - center[e]
        total += diff * diff
    return math.sqrt(total)


@numba.njit(cache=True)
def _assign_all(
    x: np.ndarray, centers: np.ndarray, labels: np.ndarray, upper: np.ndarray, lower: np.ndarray
) -> None:
    """Nearest centre of every sample, with the exact nearest and second-nearest distances."""
    for i in range(x.shape[0]):
        best, second, arg = np.inf, np.inf, 0
        for c in range(centers.shape[0]):
            dist = _distance(x[i], centers[c])
            if dist < best:
                best, second, arg = dist, best, c
            elif dist < second:
                second = dist
        labels[i], upper[i], lower[i] = arg, best, second


@numba.njit(cache=True)
def _add_center(
    x: np.ndarray, centers: np.ndarray, labels: np.ndarray, upper: np.ndarray, lower: np.ndarray
) -> None:
    """Extends a clustering by its last centre: the samples nearer to it join it.

    ``upper`` must hold the exact distances to the current centres (as :func:`_lloyd` leaves
    them); the bounds stay valid.
    """
    new = centers.shape[0] - 1
    for i in range(x.shape[0]):
        dist = _distance(x[i], centers[new])
        if dist < upper[i]:
            labels[i], upper[i], lower[i] = new, dist, min(lower[i], upper[i])
        else:
            lower[i] = min(lower[i], dist)


@numba.njit(cache=True)
def _move_sample(sums: np.ndarray, x_i: np.ndarray, source: int, target: int) -> None:
    """Moves one sample between the cluster sums ``sums`` (K, D); ``source = -1``: only adds."""
    for e in range(x_i.shape[0]):
        if source >= 0:
            sums[source, e] -= x_i[e]
        sums[target, e] += x_i[e]


@numba.njit(cache=True)
def _lloyd(
    x: np.ndarray, centers: np.ndarray, labels: np.ndarray, upper: np.ndarray,
    lower: np.ndarray, max_iter: int, tol: float,
) -> tuple[float, int]:
    """Lloyd iterations in place, with Hamerly's distance bounds (exactly Lloyd's result).

    Each sample keeps an upper bound on the distance to its centre and a lower bound on the
    distance to every other centre; when centres move the bounds are loosened by the moves, and
    only samples whose bounds overlap are measured again. An empty cluster takes the sample
    farthest from its centre.

    Args:
        x: Samples, shape ``(N, D)``.
        centers: Centres, shape ``(K, D)``, updated in place.
        labels, upper, lower: Cluster of each sample and valid bounds, shape ``(N,)``, updated.
        max_iter: Maximum number of centre updates.
        tol: Stop when the summed squared centre shift of an update is at most this.

    Returns:
        ``(inertia, n_iter)``. On return the centres are the means of their clusters and
        ``upper`` holds the exact distance of every sample to its centre.
    """
    n, d = x.shape
    k = centers.shape[0]
    sums = np.zeros((k, d))
    counts = np.zeros(k, dtype=np.intp)
    for i in range(n):
        counts[labels[i]] += 1
        _move_sample(sums, x[i], -1, labels[i])
    moved = np.empty(k)
    half_gap = np.empty(k)
    n_iter = 0
    while n_iter < max_iter:
        n_iter += 1
        shift = 0.0
        for c in range(k):
            if counts[c] == 0:  # re-seed at the farthest sample of a cluster of >= 2 samples
                far = -1
                for i in range(n):
                    if counts[labels[i]] > 1 and (far < 0 or upper[i] > upper[far]):
                        far = i
                if far < 0:  # fewer distinct samples than clusters: leave it empty
                    moved[c] = 0.0
                    continue
                counts[labels[far]] -= 1
                counts[c] = 1
                _move_sample(sums, x[far], labels[far], c)
                labels[far], upper[far], lower[far] = c, 0.0, 0.0
            squared = 0.0
            for e in range(d):
                new = sums[c, e] / counts[c]
                squared += (new - centers[c, e]) ** 2
                centers[c, e] = new
            moved[c] = math.sqrt(squared)
            shift += squared
        if shift <= tol:
            break
        for c in range(k):
            gap = np.inf
            for other in range(k):
                if other != c:
                    gap = min(gap, _distance(centers[c], centers[other]))
            half_gap[c] = 0.5 * gap
        max_moved = moved.max()
        changed = 0
        for i in range(n):
            own = labels[i]
            upper[i] += moved[own]
            lower[i] -= max_moved
            bound = max(half_gap[own], lower[i])
            if upper[i] <= bound:
                continue
            upper[i] = _distance(x[i], centers[own])
            if upper[i] <= bound:
                continue
            best, second, arg = np.inf, np.inf, 0
            for c in range(k):
                dist = _distance(x[i], centers[c])
                if dist < best:
                    best, second, arg = dist, best, c
                elif dist < second:
                    second = dist
            labels[i], upper[i], lower[i] = arg, best, second
            if arg != own:
                changed += 1
                counts[own] -= 1
                counts[arg] += 1
                _move_sample(sums, x[i], own, arg)
        if changed == 0:
            break
    # Exact centres (no drift from the incremental sums), distances and inertia.
    sums[:] = 0.0
    for i in range(n):
        _move_sample(sums, x[i], -1, labels[i])
    for c in range(k):
        if counts[c] > 0:
            for e in range(d):
                centers[c, e] = sums[c, e] / counts[c]
    inertia = 0.0
    for i in range(n):
        upper[i] = _distance(x[i], centers[labels[i]])
        inertia += upper[i] ** 2
    return inertia, n_iter


def _kmeans_sweep(
    data: _Data, k_max: int, n_init: int, max_iter: int, tol: float, seed: int
) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """Best of ``n_init`` K-means chains for every ``K = 1..k_max``.

    Each start is a chain: its ``K``-cluster run begins from its converged ``(K-1)``-cluster
    centres plus one new centre drawn by the k-means++ rule (probability proportional to the
    squared distance to the current centres), as in incremental / global K-means (Likas et al.,
    2003). Starting from a nearby optimum, Lloyd needs few iterations, and the distance bounds
    carry over. The chains are independent, so a poor optimum in one does not reach the others;
    for every ``K`` the lowest inertia over the chains wins.

    Returns:
        ``(centers, labels, inertia)`` for ``K = 1..k_max`` (centres in centred coordinates).
    """
    x = data.x
    n_samples = x.shape[0]
    tol_abs = tol * float(np.mean(data.x_sq)) / x.shape[1]  # tol relative to mean variance
    best: list[tuple[np.ndarray, np.ndarray, float] | None] = [None] * k_max
    for start in range(n_init):
        rng = _start_generator(seed, start)
        centers = x[[rng.integers(n_samples)]]
        labels = np.zeros(n_samples, dtype=np.intp)
        upper = np.sqrt(np.sum((x - centers[0]) ** 2, axis=1))
        lower = np.full(n_samples, np.inf)
        for k in range(1, k_max + 1):
            if k > 1:
                cumulative = np.cumsum(upper**2)
                if cumulative[-1] > 0.0:
                    drawn = np.searchsorted(cumulative, rng.uniform(0.0, cumulative[-1]))
                    idx = min(int(drawn), n_samples - 1)
                else:  # fewer distinct points than clusters: any point will do
                    idx = int(rng.integers(n_samples))
                centers = np.vstack((centers, x[idx]))
                _add_center(x, centers, labels, upper, lower)
            inertia, _ = _lloyd(x, centers, labels, upper, lower, max_iter, tol_abs)
            if best[k - 1] is None or inertia < best[k - 1][2]:
                best[k - 1] = (centers.copy(), labels.copy(), inertia)
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
    """K-means clustering with incremental k-means++ seeding and several seeded starts.

    Every start grows a chain of clusterings ``1, 2, ..., n_clusters``, each seeded by the
    previous optimum plus one k-means++ centre (see :func:`_kmeans_sweep`), so that ``kmeans(X,
    K)`` is exactly the ``K``-th clustering of the BIC sweep :func:`select_components`. A single
    K-means run can stall in a poor local optimum, which makes a BIC curve built from K-means alone
    jagged; the best of ``n_init`` independent chains (lowest inertia) guards against that.

    Args:
        X: Samples, shape ``(n_samples, n_dims)``, finite.
        n_clusters: Number of clusters, ``1 <= n_clusters <= n_samples``.
        n_init: Number of independent chains (starts), ``>= 1``.
        max_iter: Maximum number of Lloyd iterations per clustering, ``>= 1``.
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
    centers, labels, inertia = _kmeans_sweep(data, n_clusters, n_init, max_iter, tol, seed)[-1]
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
    labels = np.asarray(labels, dtype=np.intp)
    weights, means, cov = _cluster_parameters(data, labels, n_components, reg_covar)
    return weights, means + data.centre, cov


def _cluster_parameters(
    data: _Data, labels: np.ndarray, n_components: int, reg_covar: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The M-step (eqs. 9-12) for hard responsibilities, in one pass over the samples."""
    counts, sums, second = _cluster_moments(data.x, labels, n_components)
    counts += _EPS_COUNTS
    means = sums / counts[:, None]
    covariances = second / counts[:, None, None] - means[:, :, None] * means[:, None, :]
    n_dims = data.x.shape[1]
    covariances[:, np.arange(n_dims), np.arange(n_dims)] += reg_covar
    return counts / counts.sum(), means, covariances


@numba.njit(cache=True)
def _cluster_moments(
    x: np.ndarray, labels: np.ndarray, n_components: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-cluster sample counts (K,), sums (K, D) and sums of outer products (K, D, D)."""
    n, d = x.shape
    counts = np.zeros(n_components)
    sums = np.zeros((n_components, d))
    second = np.zeros((n_components, d, d))
    for i in range(n):
        c = labels[i]
        counts[c] += 1.0
        for e in range(d):
            sums[c, e] += x[i, e]
            for f in range(d):
                second[c, e, f] += x[i, e] * x[i, f]
    return counts, sums, second


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
        n_init: Number of K-means starts for the initialisation (see :func:`kmeans`).
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
        _, labels, _ = _kmeans_sweep(
            data, self.n_components, self.n_init, _KMEANS_MAX_ITER, _KMEANS_TOL, self.seed
        )[-1]
        self._em(data, *_cluster_parameters(data, labels, self.n_components, self.reg_covar))
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


def _total_log_likelihood(
    lifted: np.ndarray, weights: np.ndarray, means: np.ndarray, precisions: np.ndarray,
    half_log_det: np.ndarray,
) -> float:
    """``sum_i log p(x_i)`` (eq. 3) without responsibilities, for the fast BIC sweep.

    Args:
        lifted: Centred samples as rows ``(x x^T flattened, x, 1)``, shape ``(N, D*D + D + 1)``.
        weights, means, precisions, half_log_det: The mixture (centred means), see
            :func:`_precisions`.

    Returns:
        The total log-likelihood [nats]. All Mahalanobis distances come from one matrix product.
    """
    n_components, n_dims = means.shape
    p_mu = np.einsum("kde,ke->kd", precisions, means)
    coefficients = np.vstack((
        precisions.reshape(n_components, n_dims * n_dims).T,
        -2.0 * p_mu.T,
        np.einsum("kd,kd->k", means, p_mu)[None, :],
    ))
    log_coefficients = np.log(weights) + half_log_det - 0.5 * n_dims * _LOG_2PI
    return _sum_log_mixture(lifted @ coefficients, log_coefficients)


@numba.njit(cache=True)
def _sum_log_mixture(maha: np.ndarray, log_coefficients: np.ndarray) -> float:
    """``sum_i log sum_k exp(c_k - maha_ik / 2)`` by the log-sum-exp trick, row by row.

    Terms below ``exp(_LOG_NEGLIGIBLE)`` times the largest one are skipped: added to a sum of at
    least 1 they are below half a unit in the last place, so they would not change it.
    """
    n, k = maha.shape
    terms = np.empty(k)
    total = 0.0
    for i in range(n):
        top = -np.inf
        for c in range(k):
            terms[c] = log_coefficients[c] - 0.5 * max(maha[i, c], 0.0)
            top = max(top, terms[c])
        acc = 0.0
        for c in range(k):
            if terms[c] - top > _LOG_NEGLIGIBLE:
                acc += math.exp(terms[c] - top)
        total += top + math.log(acc)
    return total


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
    paper observes that the fast heuristic chooses more components than the full one (Fig. 5);
    that is not guaranteed (see the tests).

    Args:
        X: Samples, shape ``(n_samples, n_dims)``, finite.
        k_max: Largest ``K`` tried, ``1 <= k_max <= n_samples``.
        method: ``"fast"`` or ``"full"``.
        seed: Seed of the K-means starts (see :func:`kmeans`).
        reg_covar: Covariance regularisation, see :class:`GMM`.
        n_init: Number of independent K-means chains (see :func:`kmeans`).
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
    lifted = np.hstack((data.outer, data.x, np.ones((n_samples, 1)))) if method == "fast" else None
    curve = np.empty(k_max)
    runs = _kmeans_sweep(data, k_max, n_init, _KMEANS_MAX_ITER, _KMEANS_TOL, seed)
    for k, (_, labels, _) in enumerate(runs, start=1):
        weights, means, cov = _cluster_parameters(data, labels, k, reg_covar)
        if method == "fast":
            log_likelihood = _total_log_likelihood(lifted, weights, means, *_precisions(cov))
        else:
            model = GMM(k, reg_covar=reg_covar, tol=tol, max_iter=max_iter)
            model._em(data, weights, means, cov)
            log_likelihood = float(model.score_samples(X).sum())
        curve[k - 1] = _bic(log_likelihood, k, n_dims, n_samples)
    return int(np.argmin(curve)) + 1, curve
