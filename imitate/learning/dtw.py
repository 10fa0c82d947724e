r"""Dynamic time warping (paper eq. 2) and alignment of demonstrations onto one reference.

The local distance between sample ``i`` of ``a`` and sample ``j`` of ``b`` is the per-dimension
weighted Euclidean distance

.. math:: v_{ij} = \sqrt{\textstyle\sum_d \left(w_d\,(a_{id} - b_{jd})\right)^2},

so ``weights`` act as scale factors on each dimension (``dtw(a, b, w) == dtw(a * w, b * w)``). The
accumulated cost follows eq. 2 exactly: the *sum* of local distances (not squared) along a
monotone path from ``(0, 0)`` to ``(n-1, m-1)`` made of the three unit-weight steps (1, 1),
(0, 1), (1, 0). This is dtw-python's ``symmetric1`` step pattern with ``dist_method="euclidean"``;
ties are broken in its order (diagonal, then ``(i, j-1)``, then ``(i-1, j)``).

Speed: the table is filled row by row in a small compiled loop (numba), which computes each row
of local distances with the same summation order as ``scipy.spatial.distance.cdist`` (used by
dtw-python), keeps only two rows of accumulated costs, fills each row in a vectorised pass (the
diagonal and up steps) and a serial one (the left step), and records the chosen step of every
cell (one byte each); the path is read back from those steps, exactly as dtw-python does. The first
call of a process compiles the loops or loads them from numba's on-disk cache.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import ArrayLike

from imitate._numba import ensure_writable
from imitate._validation import check_samples
from imitate.errors import ImitateError

ensure_writable(__file__)  # before the kernels below are declared

__all__ = ["Alignment", "align", "default_weights", "dtw", "local_costs", "warp_to_reference"]

# Step codes recorded per cell; their order is dtw-python's tie-breaking order.
_START, _DIAGONAL, _LEFT, _UP = -1, 0, 1, 2


def _as_series(x: ArrayLike, name: str) -> np.ndarray:
    """Validates one series as a finite float array of shape ``(n_steps, n_dims)`` (one
    dimension for a 1-D one)."""
    arr = np.asarray(x, dtype=float)
    return check_samples(
        arr[:, None] if arr.ndim == 1 else arr, name, "step", "(n_steps, n_dims) or (n_steps,)",
        "; interpolate or drop missing samples first",
    )


def _pair(
    a: ArrayLike, b: ArrayLike, weights: ArrayLike | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The series ``a`` and ``b`` checked, of as many dimensions, and their weights."""
    a, b = _as_series(a, "a"), _as_series(b, "b")
    if a.shape[1] != b.shape[1]:
        raise ImitateError(
            f"a and b must have the same number of dimensions; got {a.shape[1]} and {b.shape[1]}"
        )
    return a, b, _as_weights(weights, a.shape[1])


def _as_weights(weights: ArrayLike | None, n_dims: int) -> np.ndarray:
    """Validates per-dimension weights: ``None`` -> ones, else finite, >= 0, shape ``(n_dims,)``."""
    if weights is None:
        return np.ones(n_dims)
    w = np.asarray(weights, dtype=float)
    if w.shape != (n_dims,):
        raise ImitateError(f"weights must have shape ({n_dims},); got shape {w.shape}")
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ImitateError(f"weights must be finite and >= 0; got {w}")
    return w


def local_costs(a: ArrayLike, b: ArrayLike, weights: ArrayLike | None = None) -> np.ndarray:
    """Matrix ``V`` of weighted Euclidean distances between all samples of two series.

    Args:
        a: First series, shape ``(n, n_dims)`` (or ``(n,)`` for one dimension).
        b: Second series, shape ``(m, n_dims)``.
        weights: Per-dimension scale factors, shape ``(n_dims,)``, ``>= 0``; ``None`` for ones.

    Returns:
        ``V``, shape ``(n, m)``, ``V[i, j] = ||w * (a[i] - b[j])||``, in the units of ``w * a``.

    Raises:
        ImitateError: On non-finite input, mismatched dimensions or bad weights.
    """
    a, b, w = _pair(a, b, weights)
    bt = np.ascontiguousarray((b * w).T)
    aw = a * w
    v = np.empty((a.shape[0], b.shape[0]))
    for i in range(a.shape[0]):
        _local_cost_row(aw[i], bt, v[i])
    return v


@numba.njit(cache=True)
def _local_cost_row(a_i: np.ndarray, bt: np.ndarray, out: np.ndarray) -> None:
    """Writes ``out[j] = ||a_i - bt[:, j]||`` for one sample ``a_i`` (d,) and ``bt`` (d, m).

    The squares are summed over dimensions in order from 0, as scipy's ``cdist`` does, so the
    local costs are bit-identical to dtw-python's, and exact (no cancellation) near zero.
    """
    out[:] = 0.0
    for d in range(bt.shape[0]):
        a_id = a_i[d]
        for j in range(bt.shape[1]):
            diff = a_id - bt[d, j]
            out[j] += diff * diff
    for j in range(bt.shape[1]):
        out[j] = math.sqrt(out[j])


@numba.njit(cache=True)
def _accumulate(a: np.ndarray, bt: np.ndarray) -> tuple[float, np.ndarray]:
    """Eq. 2 for already scaled series ``a`` (n, d) and ``bt`` (d, m, i.e. ``b`` transposed).

    Every cell takes the cheapest of its three predecessors; as in dtw-python, the candidates
    ``acc + v`` are compared and the first in the order diagonal, left, up wins ties. A row is
    filled in two passes: the diagonal and up candidates depend only on the previous row (an
    independent loop the compiler vectorises), then the left candidate runs along the row, the
    only serial dependency. The costs and choices are those of the three-way comparison.

    Returns:
        ``(distance, steps)``: eq. 2's ``dtw(n-1, m-1)`` and the step code chosen at every cell,
        int8 of shape ``(n, m)`` (``_START`` at ``(0, 0)``).
    """
    n, m = a.shape[0], bt.shape[1]
    prev = np.empty(m)
    cur = np.empty(m)
    v = np.empty(m)
    steps = np.empty((n, m), dtype=np.int8)
    for i in range(n):
        _local_cost_row(a[i], bt, v)
        row = steps[i]
        if i == 0:
            cur[0] = v[0]
            row[0] = _START
            for j in range(1, m):
                cur[j] = cur[j - 1] + v[j]
                row[j] = _LEFT
        else:
            cur[0] = prev[0] + v[0]
            row[0] = _UP
            for j in range(1, m):  # diagonal or up; the diagonal wins a tie
                diagonal, up = prev[j - 1] + v[j], prev[j] + v[j]
                if diagonal <= up:
                    cur[j], row[j] = diagonal, _DIAGONAL
                else:
                    cur[j], row[j] = up, _UP
            for j in range(1, m):  # left; it wins a tie against up, not against the diagonal
                left = cur[j - 1] + v[j]
                if left < cur[j] or (left == cur[j] and row[j] == _UP):
                    cur[j], row[j] = left, _LEFT
        prev, cur = cur, prev
    return prev[m - 1], steps


@numba.njit(cache=True)
def _backtrack(steps: np.ndarray) -> np.ndarray:
    """Optimal path, shape ``(L, 2)``, from ``(0, 0)`` to ``(n-1, m-1)`` along recorded steps."""
    n, m = steps.shape
    path = np.empty((n + m - 1, 2), dtype=np.intp)
    i, j = n - 1, m - 1
    k = path.shape[0]
    while True:
        k -= 1
        path[k, 0] = i
        path[k, 1] = j
        step = steps[i, j]
        if step == _START:
            break
        if step != _LEFT:
            i -= 1
        if step != _UP:
            j -= 1
    return path[k:].copy()


def _dtw_scaled(a: np.ndarray, b: np.ndarray) -> tuple[float, np.ndarray]:
    """DTW distance and step codes of two already scaled series, see :func:`_accumulate`."""
    return _accumulate(np.ascontiguousarray(a), np.ascontiguousarray(b.T))


def dtw(a: ArrayLike, b: ArrayLike, weights: ArrayLike | None = None) -> tuple[float, np.ndarray]:
    """Dynamic time warping distance and optimal warping path of two series (eq. 2).

    Args:
        a: First series, shape ``(n, n_dims)`` (or ``(n,)``).
        b: Second series, shape ``(m, n_dims)`` (or ``(m,)``).
        weights: Per-dimension scale factors, shape ``(n_dims,)``, ``>= 0``; ``None`` for ones.

    Returns:
        ``(distance, path)``: ``distance`` is the sum of local distances along the optimal path
        (eq. 2's ``dtw(n, m)``); ``path`` is an int array of shape ``(L, 2)``, rows
        ``(i, j)`` from ``(0, 0)`` to ``(n-1, m-1)``, each step one of (1, 1), (0, 1), (1, 0).

    Raises:
        ImitateError: On non-finite input, mismatched dimensions or bad weights.

    Examples:
        >>> d, path = dtw([0.0, 1.0, 2.0], [0.0, 0.0, 1.0, 2.0])
        >>> float(d), path.tolist()
        (0.0, [[0, 0], [0, 1], [1, 2], [2, 3]])
    """
    a, b, w = _pair(a, b, weights)
    distance, steps = _dtw_scaled(a * w, b * w)
    return float(distance), _backtrack(steps)


def default_weights(demos: Sequence[np.ndarray]) -> np.ndarray:
    """Inverse pooled standard deviation of each dimension, so every dimension counts alike.

    Args:
        demos: Demonstrations, each of shape ``(n_steps_i, n_dims)``.

    Returns:
        Weights, shape ``(n_dims,)``, in the inverse units of each dimension; a dimension that is
        constant over all demonstrations gets weight 0 (it cannot inform the alignment).
    """
    std = np.concatenate(demos, axis=0).std(axis=0)
    return np.divide(1.0, std, out=np.zeros_like(std), where=std > 0)


def warp_to_reference(demo: np.ndarray, path: np.ndarray, n_reference: int) -> np.ndarray:
    """Warps a demonstration onto the time line of the reference along a DTW path.

    Every reference step takes the mean of the demonstration samples matched to it, so the
    result has the reference's length (Fig. 3: the indices of the path morph one signal to
    match the other).

    Args:
        demo: Demonstration, shape ``(n_steps, n_dims)``.
        path: DTW path against the reference, shape ``(L, 2)``, columns (demo step, reference
            step), from :func:`dtw` with the demonstration as first argument.
        n_reference: Number of steps of the reference.

    Returns:
        Warped demonstration, shape ``(n_reference, n_dims)``.
    """
    counts = np.bincount(path[:, 1], minlength=n_reference).astype(float)
    sums = np.zeros((n_reference, demo.shape[1]))
    np.add.at(sums, path[:, 1], demo[path[:, 0]])
    return sums / counts[:, None]


@dataclass(frozen=True)
class Alignment:
    """Demonstrations warped onto one reference demonstration.

    Attributes:
        aligned: Warped demonstrations, shape ``(n_demos, n_steps, n_dims)`` with ``n_steps``
            the reference's length; ``aligned[reference]`` is the reference itself.
        reference: Index of the reference demonstration.
        paths: One DTW path per demonstration against the reference, shape ``(L_i, 2)``,
            columns (demonstration step, reference step).
        distances: Pairwise DTW distances, shape ``(n_demos, n_demos)``, symmetric, zero diagonal.
        weights: Per-dimension scale factors used by the local distance, shape ``(n_dims,)``.
    """

    aligned: np.ndarray
    reference: int
    paths: tuple[np.ndarray, ...]
    distances: np.ndarray
    weights: np.ndarray


def align(
    demos: Sequence[ArrayLike],
    *,
    weights: ArrayLike | None = None,
    reference: int | None = None,
) -> Alignment:
    """Aligns all demonstrations onto one reference with DTW so that they share its length.

    DTW is solved for every pair (the step codes of each pair, one byte per cell, are kept until
    the reference is known). The reference is the medoid (the demonstration with the smallest
    summed DTW distance to the others, lowest index on ties) unless given.

    Args:
        demos: At least 2 demonstrations, each of shape ``(n_steps_i, n_dims)``, finite.
        weights: Per-dimension scale factors, shape ``(n_dims,)``; ``None`` uses
            :func:`default_weights` (inverse pooled standard deviation).
        reference: Index of the reference demonstration; ``None`` for the medoid.

    Returns:
        The :class:`Alignment`.

    Raises:
        ImitateError: Fewer than 2 demonstrations, non-finite samples, mismatched dimensions,
            bad weights or a reference index out of range.
    """
    if len(demos) < 2:
        raise ImitateError(f"align needs at least 2 demonstrations; got {len(demos)}")
    series = [_as_series(d, f"demos[{k}]") for k, d in enumerate(demos)]
    n_dims = series[0].shape[1]
    for k, s in enumerate(series):
        if s.shape[1] != n_dims:
            raise ImitateError(
                f"all demonstrations must have the same number of dimensions; demos[0] has "
                f"{n_dims}, demos[{k}] has {s.shape[1]}"
            )
    n_demos = len(series)
    if reference is not None and not 0 <= reference < n_demos:
        raise ImitateError(f"reference must be in [0, {n_demos - 1}]; got {reference}")
    w = default_weights(series) if weights is None else _as_weights(weights, n_dims)
    scaled = [s * w for s in series]

    distances = np.zeros((n_demos, n_demos))
    steps = {}
    for p in range(n_demos):
        for q in range(p + 1, n_demos):
            distances[p, q], steps[p, q] = _dtw_scaled(scaled[p], scaled[q])
            distances[q, p] = distances[p, q]
    if reference is None:
        reference = int(np.argmin(distances.sum(axis=1)))

    n_ref = len(series[reference])
    paths = []
    aligned = np.empty((n_demos, n_ref, n_dims))
    for d in range(n_demos):
        if d == reference:
            path = np.column_stack((np.arange(n_ref), np.arange(n_ref)))
        else:
            path = _backtrack(steps[min(d, reference), max(d, reference)])
            if d > reference:
                path = path[:, ::-1]
        paths.append(path)
        aligned[d] = warp_to_reference(series[d], path, n_ref)
    return Alignment(
        aligned=aligned, reference=reference, paths=tuple(paths), distances=distances, weights=w
    )
