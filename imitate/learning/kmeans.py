"""K-means clustering, the start of EM and of the BIC sweep (paper section IV-B).

Lloyd's algorithm with Hamerly's distance bounds (exactly Lloyd's iterates), on samples ``x_i``
of shape ``(N, D)``. The clusterings for ``K = 1, 2, ...`` grow incrementally in ``n_init``
independent chains, each ``K`` from the previous optimum plus one k-means++ centre; for every
``K`` the lowest inertia over the chains wins.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike

from imitate._numba import ensure_writable
from imitate._validation import check_n_components, check_samples
from imitate.errors import ImitateError

ensure_writable(__file__)  # before the kernels below are declared

__all__ = ["KMeansResult", "kmeans"]

# scikit-learn's K-means defaults, used for the initialisation of EM and for the BIC sweep.
_MAX_ITER = 100
_TOL = 1e-4
# scikit-learn adds this to the soft counts so that an empty component does not divide by zero.
_EPS_COUNTS = 10.0 * np.finfo(float).eps


@dataclass(frozen=True)
class KMeansResult:
    """Outcome of :func:`kmeans`.

    Attributes:
        centres: Cluster centres, shape ``(n_clusters, n_dims)``.
        labels: Cluster of each sample, shape ``(n_samples,)``, values in ``[0, n_clusters)``.
        inertia: Sum of squared distances of the samples to their centres.
    """

    centres: np.ndarray
    labels: np.ndarray
    inertia: float


def _start_generator(seed: int, start: int) -> np.random.Generator:
    """Generator of one K-means start (one chain of K = 1, 2, ... clusterings)."""
    return np.random.default_rng([seed, start])


@numba.njit(cache=True)
def _argsort(keys: np.ndarray, order: np.ndarray) -> None:
    """``order[:] = np.argsort(keys)`` for a few keys ``(k,)``, by a stable insertion sort (NaN
    last): what numba's ``np.argsort`` does for up to 15 keys, without compiling its quicksort
    (seconds per array type)."""
    for i in range(keys.shape[0]):
        order[i] = i
    for i in range(1, keys.shape[0]):
        moving = order[i]
        key = keys[moving]
        j = i
        while j > 0:
            other = keys[order[j - 1]]
            if not (key < other or (other != other and key == key)):
                break
            order[j] = order[j - 1]
            j -= 1
        order[j] = moving


@numba.njit(cache=True)
def _copy_row(source: np.ndarray, target: np.ndarray) -> None:
    """``target[:] = source`` for 1-D arrays of one length, as a loop: numba's array assignment
    compiles a shape check whose error message alone costs seconds of compilation."""
    for e in range(source.shape[0]):
        target[e] = source[e]


@numba.njit(cache=True)
def _distance(x_i: np.ndarray, centre: np.ndarray) -> float:
    """Euclidean distance between one sample and one centre, both of shape ``(D,)``."""
    total = 0.0
    for e in range(x_i.shape[0]):
        diff = x_i[e] - centre[e]
        total += diff * diff
    return math.sqrt(total)


@numba.njit(cache=True)
def _assign_all(
    x: np.ndarray, centres: np.ndarray, labels: np.ndarray, upper: np.ndarray, lower: np.ndarray
) -> None:
    """Nearest centre of every sample, with the exact nearest and second-nearest distances."""
    for i in range(x.shape[0]):
        best, second, arg = np.inf, np.inf, 0
        for c in range(centres.shape[0]):
            dist = _distance(x[i], centres[c])
            if dist < best:
                best, second, arg = dist, best, c
            elif dist < second:
                second = dist
        labels[i], upper[i], lower[i] = arg, best, second


@numba.njit(cache=True)
def _nearest_two(
    x_i: np.ndarray, centres: np.ndarray, order: np.ndarray, keys: np.ndarray
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
        dist = _distance(x_i, centres[c])
        if dist < best or (dist == best and c < arg):
            best, second, arg = dist, best, c
        elif dist < second:
            second = dist
    return arg, best, second


@numba.njit(cache=True)
def _add_centre(
    x: np.ndarray, centres: np.ndarray, labels: np.ndarray, upper: np.ndarray, lower: np.ndarray
) -> None:
    """Extends a clustering by its last centre: the samples nearer to it join it.

    ``upper`` must hold the exact distances to the current centres (as :func:`_lloyd` leaves
    them); the bounds stay valid.
    """
    new = centres.shape[0] - 1
    for i in range(x.shape[0]):
        dist = _distance(x[i], centres[new])
        if dist < upper[i]:
            labels[i], upper[i], lower[i] = new, dist, min(lower[i], upper[i])
        else:
            lower[i] = min(lower[i], dist)


@numba.njit(cache=True)
def _move_sample(sums: np.ndarray, x_i: np.ndarray, source: int, target: int) -> None:
    """Moves one sample between the cluster sums ``sums`` (K, D)."""
    for e in range(x_i.shape[0]):
        sums[source, e] -= x_i[e]
        sums[target, e] += x_i[e]


@numba.njit(cache=True)
def _add_sample(sums: np.ndarray, x_i: np.ndarray, target: int) -> None:
    """Adds one sample to the cluster sums ``sums`` (K, D) (a constant ``source`` of
    :func:`_move_sample` would compile it a second time, for that constant)."""
    for e in range(x_i.shape[0]):
        sums[target, e] += x_i[e]


@numba.njit(cache=True)
def _lloyd(
    x: np.ndarray, centres: np.ndarray, labels: np.ndarray, upper: np.ndarray,
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
        centres: Centres, shape ``(K, D)``, updated in place.
        labels: Cluster of each sample, shape ``(N,)``, updated in place.
        upper: Valid upper bound on each sample's distance to its centre, shape ``(N,)``,
            updated in place.
        lower: Valid lower bound on each sample's distance to every other centre, shape
            ``(N,)``, updated in place.
        max_iter: Maximum number of centre updates.
        tol: Stop when the summed squared centre shift of an update is at most this.

    Returns:
        ``(inertia, n_iter)``. On return the centres are the means of their clusters and
        ``upper`` holds the exact distance of every sample to its centre.
    """
    n, d = x.shape
    k = centres.shape[0]
    sums = np.zeros((k, d))
    counts = np.zeros(k, dtype=np.intp)
    for i in range(n):
        counts[labels[i]] += 1
        _add_sample(sums, x[i], labels[i])
    moved = np.empty(k)
    half_gap = np.empty(k)
    order = np.empty(k, dtype=np.intp)
    keys = np.empty(k)
    firsts = np.empty(k)
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
                squared += (new - centres[c, e]) ** 2
                centres[c, e] = new
            moved[c] = math.sqrt(squared)
            shift += squared
        if shift <= tol:
            break
        for c in range(k):
            firsts[c] = centres[c, 0]
        _argsort(firsts, order)
        for rank in range(k):
            keys[rank] = firsts[order[rank]]
        for rank in range(k):  # nearest other centre, outward in the first coordinate
            c = order[rank]
            gap = np.inf
            for other in range(rank + 1, k):
                if keys[other] - keys[rank] >= gap:
                    break
                gap = min(gap, _distance(centres[c], centres[order[other]]))
            for other in range(rank - 1, -1, -1):
                if keys[rank] - keys[other] >= gap:
                    break
                gap = min(gap, _distance(centres[c], centres[order[other]]))
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
            upper[i] = _distance(x[i], centres[own])
            if upper[i] <= bound:
                continue
            arg, best, second = _nearest_two(x[i], centres, order, keys)
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
        _add_sample(sums, x[i], labels[i])
    for c in range(k):
        if counts[c] > 0:
            for e in range(d):
                centres[c, e] = sums[c, e] / counts[c]
    inertia = 0.0
    for i in range(n):
        upper[i] = _distance(x[i], centres[labels[i]])
        inertia += upper[i] ** 2
    return inertia, n_iter


@numba.njit(cache=True)
def _kmeans_chains(
    x: np.ndarray, first: np.ndarray, draws: np.ndarray, max_iter: int, tol: float,
    best_centres: np.ndarray, best_labels: np.ndarray, best_inertia: np.ndarray,
) -> None:
    """Grows every chain ``K = 1..k_max`` and keeps the lowest-inertia clustering of each ``K``.

    Args:
        x: Samples, shape ``(N, D)``.
        first: Index of the first centre of every chain, shape ``(n_init,)``.
        draws: Uniform numbers in ``[0, 1)`` that pick the k-means++ centre added at ``K = 2..``,
            shape ``(n_init, k_max - 1)``.
        max_iter: Maximum number of centre updates per Lloyd run, see :func:`_lloyd`.
        tol: Lloyd's tolerance on the summed squared centre shift, see :func:`_lloyd`.
        best_centres: Output, shape ``(k_max, k_max, D)``; row ``K-1`` holds ``K`` centres.
        best_labels: Output, shape ``(k_max, N)``.
        best_inertia: Output, shape ``(k_max,)``, filled with ``inf`` by the caller.
    """
    n, d = x.shape
    k_max = best_labels.shape[0]
    centres = np.empty((k_max, d))
    labels = np.empty(n, dtype=np.intp)
    upper = np.empty(n)
    lower = np.empty(n)
    cumulative = np.empty(n)
    for start in range(first.shape[0]):
        _copy_row(x[first[start]], centres[0])
        _assign_all(x, centres[:1], labels, upper, lower)
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
                _copy_row(x[idx], centres[k - 1])
                _add_centre(x, centres[:k], labels, upper, lower)
            inertia, _ = _lloyd(x, centres[:k], labels, upper, lower, max_iter, tol)
            if inertia < best_inertia[k - 1]:
                best_inertia[k - 1] = inertia
                for c in range(k):
                    _copy_row(centres[c], best_centres[k - 1, c])
                for i in range(n):
                    best_labels[k - 1, i] = labels[i]


@dataclass(frozen=True)
class _Sweep:
    """Best K-means clustering for every ``K = 1..k_max`` (see :func:`_kmeans_sweep`)."""

    centres: np.ndarray  # (k_max, k_max, D); row K-1 holds K centres
    labels: np.ndarray  # (k_max, N)
    inertia: np.ndarray  # (k_max,)


def _kmeans_sweep(
    X: np.ndarray, k_max: int, n_init: int, seed: int, max_iter: int = _MAX_ITER,
    tol: float = _TOL,
) -> _Sweep:
    """Best of ``n_init`` K-means chains for every ``K = 1..k_max``, on validated samples.

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
        centres=np.zeros((k_max, k_max, n_dims)),
        labels=np.empty((k_max, n_samples), dtype=np.intp),
        inertia=np.full(k_max, np.inf),
    )
    _kmeans_chains(X, first, draws, max_iter, tol_abs, sweep.centres, sweep.labels, sweep.inertia)
    return sweep


def kmeans(
    X: ArrayLike,
    n_clusters: int,
    *,
    n_init: int = 3,
    max_iter: int = _MAX_ITER,
    tol: float = _TOL,
    seed: int = 0,
) -> KMeansResult:
    """K-means clustering with incremental k-means++ seeding and several seeded starts.

    Every start grows a chain of clusterings ``1, 2, ..., n_clusters``, each seeded by the
    previous optimum plus one k-means++ centre (see :func:`_kmeans_sweep`), so that ``kmeans(X,
    K)`` is exactly the ``K``-th clustering of the full BIC sweep
    :func:`imitate.learning.bic.bic_sweep`. A
    single K-means run can stall in a poor local optimum, which makes a BIC curve built from
    K-means alone jagged; the best of ``n_init`` independent chains (lowest inertia) guards
    against that.

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
    X = check_samples(X)
    check_n_components(n_clusters, X.shape[0])
    if n_init < 1 or max_iter < 1:
        raise ImitateError(f"n_init and max_iter must be >= 1; got {n_init} and {max_iter}")
    sweep = _kmeans_sweep(X, n_clusters, n_init, seed, max_iter, tol)
    return KMeansResult(
        centres=sweep.centres[-1], labels=sweep.labels[-1], inertia=float(sweep.inertia[-1])
    )
