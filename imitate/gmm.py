r"""Gaussian mixture models (paper eqs. 3-12): K-means initialisation, EM, BIC model selection.

Notation (the paper's): ``N`` samples ``x_i`` of dimension ``D`` (time plus task space), ``K``
components with priors ``pi_k``, means ``mu_k`` and covariances ``Sigma_k``.

Numerics follow scikit-learn's ``GaussianMixture(covariance_type="full")`` so that both reach the
same log-likelihood from the same start: densities are evaluated in log space through the
Cholesky factor of each covariance (no explicit inverse of ``Sigma_k``), responsibilities are
normalised with the log-sum-exp trick (terms below ``exp(-50)`` of the largest are flushed to
zero), and ``reg_covar`` is added to the diagonal of every covariance. The regularisation is
also what keeps duplicated points (a cluster of identical samples has a zero covariance) usable:
such a component gets the covariance ``reg_covar * I``.

Model selection (eqs. 5-7). The paper's eq. 6 divides the log-likelihood by ``N``; combined with
eq. 5's penalty ``P ln N`` that makes the penalty dominate and always selects ``K = 1``. We use
the total log-likelihood, the standard BIC (``BIC = -2 sum_i log p(x_i) + P ln N``, as
scikit-learn's ``GaussianMixture.bic``), with ``P`` from eq. 7.

Speed. Everything per sample runs as compiled loops (numba), one call per K-means sweep, per EM
fit and per likelihood. K-means is Lloyd's algorithm with Hamerly's distance bounds (exactly
Lloyd's iterates, but most samples are not measured again once centres move little), and the
clusterings for ``K = 1, 2, ...`` grow incrementally, each from the previous optimum plus one
k-means++ centre, in ``n_init`` independent chains. Densities use the Cholesky factor ``L_k`` of
each covariance: ``z = L_k^{-1} (x - mu_k)`` is built one dimension at a time, and its partial
squared norm is the Mahalanobis distance of the leading dimensions, a lower bound of the full
one; a component is dropped for a sample as soon as that bound puts it below the flush threshold
relative to the best component so far. With time as the first dimension most components are
dropped after one multiplication, so a density pass costs about ``N (K + a few D^2)`` rather
than ``N K D^2``. The EM M-step accumulates only the responsibilities that were not flushed.
The first call of a process compiles the loops (about 30 s on a 2-core CPU) or loads them from
numba's on-disk cache (about 1 s).
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
    "BicSweep",
    "KMeansResult",
    "bic_sweep",
    "kmeans",
    "kmeans_parameters",
    "n_parameters",
    "select_components",
]

_LOG_2PI = np.log(2.0 * np.pi)
# scikit-learn adds this to the soft counts so that an empty component does not divide by zero.
_EPS_COUNTS = 10.0 * np.finfo(float).eps
# Responsibilities below exp(-50) ~ 2e-22 of a sample's largest are flushed to 0: over all N
# samples they add less than N * 2e-22 to a soft count (below round-off for any component that
# holds a hundredth of a sample), and skipping them lets most components go unevaluated.
_LOG_FLUSH = -50.0
# exp(-38) ~ 3e-17 < 2^-53 / 2: negligible next to a term exp(0) = 1 (likelihood-only sums).
_LOG_NEGLIGIBLE = -38.0
# K-means defaults (scikit-learn's) used for the initialisation of EM and for the BIC sweep.
_KMEANS_MAX_ITER = 100
_KMEANS_TOL = 1e-4


def _check_data(X: ArrayLike, name: str = "X") -> np.ndarray:
    """Validates samples as a finite float array of shape ``(n_samples, n_dims)``."""
    arr = np.ascontiguousarray(X, dtype=float)
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
def _nearest_two(
    x_i: np.ndarray, centers: np.ndarray, order: np.ndarray, keys: np.ndarray
) -> tuple[int, float, float]:
    """Nearest centre of one sample with the exact nearest and second-nearest distances.

    ``order`` lists the centres by their first coordinate, ``keys`` holds those coordinates in
    that order. The first-coordinate gap ``|x_0 - c_0|`` is a lower bound of the distance, so
    the centres are visited outward from the sample's first coordinate and the search stops
    once the gap on both sides reaches the second-nearest distance. On time-stacked data (time
    first) that is a few centres instead of all.
    """
    k = keys.shape[0]
    t = x_i[0]
    right = np.searchsorted(keys, t)
    left = right - 1
    best, second, arg = np.inf, np.inf, 0
    while left >= 0 or right < k:
        gap_left = t - keys[left] if left >= 0 else np.inf
        gap_right = keys[right] - t if right < k else np.inf
        if gap_left <= gap_right:
            if gap_left >= second:
                break
            c = order[left]
            left -= 1
        else:
            if gap_right >= second:
                break
            c = order[right]
            right += 1
        dist = _distance(x_i, centers[c])
        if dist < best or (dist == best and c < arg):
            best, second, arg = dist, best, c
        elif dist < second:
            second = dist
    return arg, best, second


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
    distance to every other centre; when centres move the bounds are loosened by the moves (the
    lower bound by the largest move among the other centres), and only samples whose bounds
    overlap are measured again. An empty cluster takes the sample
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
        order = np.argsort(centers[:, 0])
        keys = centers[order, 0]
        for rank in range(k):  # nearest other centre, outward in the first coordinate
            c = order[rank]
            gap = np.inf
            for other in range(rank + 1, k):
                if keys[other] - keys[rank] >= gap:
                    break
                gap = min(gap, _distance(centers[c], centers[order[other]]))
            for other in range(rank - 1, -1, -1):
                if keys[rank] - keys[other] >= gap:
                    break
                gap = min(gap, _distance(centers[c], centers[order[other]]))
            half_gap[c] = 0.5 * gap
        fastest, max_moved, second_moved = 0, -1.0, 0.0
        for c in range(k):
            if moved[c] > max_moved:
                fastest, max_moved, second_moved = c, moved[c], max(max_moved, 0.0)
            elif moved[c] > second_moved:
                second_moved = moved[c]
        changed = 0
        for i in range(n):
            own = labels[i]
            upper[i] += moved[own]
            lower[i] -= second_moved if own == fastest else max_moved  # other centres' moves
            bound = max(half_gap[own], lower[i])
            if upper[i] <= bound:
                continue
            upper[i] = _distance(x[i], centers[own])
            if upper[i] <= bound:
                continue
            arg, best, second = _nearest_two(x[i], centers, order, keys)
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


@numba.njit(cache=True)
def _kmeans_chains(
    x: np.ndarray, first: np.ndarray, draws: np.ndarray, max_iter: int, tol: float,
    best_centers: np.ndarray, best_labels: np.ndarray, best_inertia: np.ndarray,
) -> None:
    """Grows every chain ``K = 1..k_max`` and keeps the lowest-inertia clustering of each ``K``.

    Args:
        x: Samples, shape ``(N, D)``.
        first: Index of the first centre of every chain, shape ``(n_init,)``.
        draws: Uniform numbers in ``[0, 1)`` that pick the k-means++ centre added at ``K = 2..``,
            shape ``(n_init, k_max - 1)``.
        max_iter, tol: Lloyd's limits, see :func:`_lloyd`.
        best_centers: Output, shape ``(k_max, k_max, D)``; row ``K-1`` holds ``K`` centres.
        best_labels: Output, shape ``(k_max, N)``.
        best_inertia: Output, shape ``(k_max,)``, filled with ``inf`` by the caller.
    """
    n, d = x.shape
    k_max = best_labels.shape[0]
    centers = np.empty((k_max, d))
    labels = np.empty(n, dtype=np.intp)
    upper = np.empty(n)
    lower = np.empty(n)
    cumulative = np.empty(n)
    for start in range(first.shape[0]):
        centers[0] = x[first[start]]
        _assign_all(x, centers[:1], labels, upper, lower)
        for k in range(1, k_max + 1):
            if k > 1:  # k-means++: probability proportional to the squared distance
                total = 0.0
                for i in range(n):
                    total += upper[i] * upper[i]
                    cumulative[i] = total
                if total > 0.0:
                    idx = min(np.searchsorted(cumulative, draws[start, k - 2] * total), n - 1)
                else:  # fewer distinct points than clusters: any point will do
                    idx = min(int(draws[start, k - 2] * n), n - 1)
                centers[k - 1] = x[idx]
                _add_center(x, centers[:k], labels, upper, lower)
            inertia, _ = _lloyd(x, centers[:k], labels, upper, lower, max_iter, tol)
            if inertia < best_inertia[k - 1]:
                best_inertia[k - 1] = inertia
                best_centers[k - 1, :k] = centers[:k]
                best_labels[k - 1] = labels


@dataclass(frozen=True)
class _Sweep:
    """Best K-means clustering for every ``K = 1..k_max`` (see :func:`_kmeans_sweep`)."""

    centers: np.ndarray  # (k_max, k_max, D); row K-1 holds K centres
    labels: np.ndarray  # (k_max, N)
    inertia: np.ndarray  # (k_max,)


def _kmeans_sweep(
    X: np.ndarray, k_max: int, n_init: int, max_iter: int, tol: float, seed: int
) -> _Sweep:
    """Best of ``n_init`` K-means chains for every ``K = 1..k_max``.

    Each start is a chain: its ``K``-cluster run begins from its converged ``(K-1)``-cluster
    centres plus one new centre drawn by the k-means++ rule (probability proportional to the
    squared distance to the current centres), as in incremental / global K-means (Likas et al.,
    2003). Starting from a nearby optimum, Lloyd needs few iterations, and the distance bounds
    carry over. The chains are independent, so a poor optimum in one does not reach the others;
    for every ``K`` the lowest inertia over the chains wins. Start ``i`` draws its first centre
    and then one uniform number per added centre from ``default_rng([seed, i])``.
    """
    n_samples, n_dims = X.shape
    first = np.empty(n_init, dtype=np.intp)
    draws = np.empty((n_init, k_max - 1))
    for start in range(n_init):
        rng = _start_generator(seed, start)
        first[start] = rng.integers(n_samples)
        draws[start] = rng.random(k_max - 1)
    tol_abs = tol * float(np.mean(np.var(X, axis=0)))  # relative to the mean variance
    sweep = _Sweep(
        centers=np.zeros((k_max, k_max, n_dims)),
        labels=np.empty((k_max, n_samples), dtype=np.intp),
        inertia=np.full(k_max, np.inf),
    )
    _kmeans_chains(X, first, draws, max_iter, tol_abs, sweep.centers, sweep.labels, sweep.inertia)
    return sweep


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
    sweep = _kmeans_sweep(X, n_clusters, n_init, max_iter, tol, seed)
    return KMeansResult(
        centers=sweep.centers[-1], labels=sweep.labels[-1], inertia=float(sweep.inertia[-1])
    )


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
    X = _check_data(X)
    return _cluster_parameters(X, np.asarray(labels, dtype=np.intp), n_components, reg_covar)


@numba.njit(cache=True)
def _cluster_parameters(
    x: np.ndarray, labels: np.ndarray, n_components: int, reg_covar: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The M-step (eqs. 9-12) for hard responsibilities: counts and means in one pass over the
    samples, covariances about those means in a second (no cancellation)."""
    n, d = x.shape
    counts = np.zeros(n_components)
    means = np.zeros((n_components, d))
    cov = np.zeros((n_components, d, d))
    for i in range(n):
        c = labels[i]
        counts[c] += 1.0
        for e in range(d):
            means[c, e] += x[i, e]
    counts += _EPS_COUNTS
    for c in range(n_components):
        means[c] /= counts[c]
    diff = np.empty(d)
    for i in range(n):
        c = labels[i]
        for e in range(d):
            diff[e] = x[i, e] - means[c, e]
        for e in range(d):
            for f in range(e + 1):
                cov[c, e, f] += diff[e] * diff[f]
    for c in range(n_components):
        for e in range(d):
            for f in range(e + 1):
                cov[c, e, f] /= counts[c]
                cov[c, f, e] = cov[c, e, f]
            cov[c, e, e] += reg_covar
    return counts / counts.sum(), means, cov


# ---------------------------------------------------------------------------------------------
# Gaussian densities and EM


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


def _exp_flushed(a: np.ndarray) -> np.ndarray:
    """``exp(a)`` with entries where ``a < -50`` set to exactly 0 (see ``_LOG_FLUSH``)."""
    return np.exp(a, out=np.zeros_like(a), where=a >= _LOG_FLUSH)


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
            ``(weights, means, covariances)``, see :func:`kmeans_parameters`.
        """
        X = _check_data(X)
        _check_n_components(self.n_components, X.shape[0])
        labels = _kmeans_sweep(
            X, self.n_components, self.n_init, _KMEANS_MAX_ITER, _KMEANS_TOL, self.seed
        ).labels[-1]
        return _cluster_parameters(X, labels, self.n_components, self.reg_covar)

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

    def _em(self, xt: np.ndarray, weights: np.ndarray, means: np.ndarray, cov: np.ndarray) -> None:
        """EM (see :func:`_em_loop`) on sorted, transposed samples ``xt`` (D, N) from given
        parameters, which it may overwrite."""
        n_iter, converged, lower_bound, ok = _em_loop(
            xt, weights, means, cov, self.reg_covar, self.tol, self.max_iter
        )
        if not ok:
            raise _not_positive_definite()
        self.n_iter_, self.converged_, self.lower_bound_ = n_iter, converged, lower_bound
        self._set_parameters(weights, means, cov)

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
        self._em(_sorted_transposed(X)[0], *(np.array(a, order="C") for a in (
            init.weights_, init.means_, init.covariances_)))
        return self

    def _check_fitted(self, X: ArrayLike) -> np.ndarray:
        if not hasattr(self, "means_"):
            raise ImitateError("this GMM is not fitted yet; call fit(X) or from_parameters first")
        X = _check_data(X)
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
        """Bayesian information criterion (eq. 5 with the *total* log-likelihood, see module)."""
        log_norm = self.score_samples(X)
        return _bic(float(log_norm.sum()), self.n_components, self.means_.shape[1], log_norm.size)


# ---------------------------------------------------------------------------------------------
# Choosing K


def _bic(log_likelihood: float, n_components: int, n_dims: int, n_samples: int) -> float:
    return -2.0 * log_likelihood + n_parameters(n_components, n_dims) * np.log(n_samples)


@numba.njit(cache=True)
def _cluster_log_likelihood(
    x: np.ndarray, xt: np.ndarray, labels: np.ndarray, k: int, reg_covar: float
) -> float:
    """``sum_i log p(x_i)`` (eq. 3) of the mixture taken from hard clusters (the fast BIC).

    Terms below ``exp(-38)`` of a sample's largest term are left out: added to a sum of at least 1
    they are below half a unit in the last place. ``x`` (N, D) are the samples, ``xt`` the same
    sorted and transposed (see :func:`_e_step`). Returns ``nan`` if a covariance is singular.
    """
    weights, means, cov = _cluster_parameters(x, labels, k, reg_covar)
    prec_chol = np.zeros_like(cov)
    log_coef = np.empty(k)
    if not _factor(weights, cov, prec_chol, log_coef):
        return np.nan
    return _e_step(xt, means, prec_chol, log_coef, _LOG_NEGLIGIBLE, np.empty((0, k))).sum()


_BIC_METHODS = ("fast", "full")


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
        """The K-means start of the chosen ``K``, as :meth:`GMM.initial_parameters` gives it."""
        return kmeans_parameters(X, self.labels[self.k - 1], self.k, reg_covar)


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

    Returns ``(k, bic_curve)`` (curve of shape ``(k_max,)``); see :func:`bic_sweep`, which takes
    the same arguments and also keeps the K-means clusterings.
    """
    sweep = bic_sweep(X, k_max, method, seed, reg_covar=reg_covar, n_init=n_init, tol=tol,
                      max_iter=max_iter)
    return sweep.k, sweep.curve


def bic_sweep(
    X: ArrayLike,
    k_max: int = 30,
    method: str = "fast",
    seed: int = 0,
    *,
    reg_covar: float = 1e-6,
    n_init: int = 3,
    tol: float = 1e-3,
    max_iter: int = 100,
) -> BicSweep:
    """BIC for ``K = 1..k_max`` and the ``K`` of the smallest one.

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
        The :class:`BicSweep`: the chosen ``K``, the BIC curve and the K-means clusterings, so
        that ``GMM(sweep.k, seed=seed, n_init=n_init).fit(X)`` equals EM from
        ``sweep.initial_parameters(X)`` without clustering again.

    Raises:
        ImitateError: On a bad method, ``k_max`` out of range or non-finite samples.
    """
    if method not in _BIC_METHODS:
        raise ImitateError(f"method must be one of {_BIC_METHODS}; got {method!r}")
    X = _check_data(X)
    _check_n_components(k_max, X.shape[0])
    n_samples, n_dims = X.shape
    labels = _kmeans_sweep(X, k_max, n_init, _KMEANS_MAX_ITER, _KMEANS_TOL, seed).labels
    xt = _sorted_transposed(X)[0]
    curve = np.empty(k_max)
    for k in range(1, k_max + 1):
        if method == "fast":
            log_likelihood = _cluster_log_likelihood(X, xt, labels[k - 1], k, reg_covar)
            if np.isnan(log_likelihood):
                raise _not_positive_definite()
        else:
            model = GMM(k, reg_covar=reg_covar, tol=tol, max_iter=max_iter)
            model._em(xt, *_cluster_parameters(X, labels[k - 1], k, reg_covar))
            log_likelihood = float(model.score_samples(X).sum())
        curve[k - 1] = _bic(log_likelihood, k, n_dims, n_samples)
    return BicSweep(k=int(np.argmin(curve)) + 1, curve=curve, labels=labels)
