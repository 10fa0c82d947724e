r"""Dynamic time warping (paper eq. 2) and alignment of demonstrations onto one reference.

The local distance between sample ``i`` of ``a`` and sample ``j`` of ``b`` is the per-dimension
weighted Euclidean distance

.. math:: v_{ij} = \sqrt{\textstyle\sum_d \left(w_d\,(a_{id} - b_{jd})\right)^2},

so ``weights`` act as scale factors on each dimension (``dtw(a, b, w) == dtw(a * w, b * w)``). The
accumulated cost follows eq. 2 exactly: the *sum* of local distances (not squared) along a
monotone path from ``(0, 0)`` to ``(n-1, m-1)`` made of the three unit-weight steps (1, 1),
(0, 1), (1, 0). This is dtw-python's ``symmetric1`` step pattern with ``dist_method="euclidean"``;
ties are broken in its order (diagonal, then ``(i, j-1)``, then ``(i-1, j)``).

Speed without compiled code: all cells of one anti-diagonal ``i + j = k`` depend only on the two
previous anti-diagonals, so the table is filled as a wavefront, three vectorised numpy calls per
anti-diagonal, on a skewed (zero-copy) view of the local costs. Many pairs are processed side by
side (the pair index is the innermost, contiguous axis), which is what :func:`align` does for all
pairs of demonstrations at once. The local costs use the Gram-matrix formula with an exact
recomputation of near-zero distances, so a series has distance exactly 0 to itself.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.lib.stride_tricks import as_strided
from numpy.typing import ArrayLike

from imitate.errors import ImitateError

__all__ = ["Alignment", "align", "default_weights", "dtw", "local_costs", "warp_to_reference"]

# Cells whose squared distance from the Gram-matrix formula is below this fraction of the squared
# norms are recomputed by direct differences, so that near-zero distances are exact (the formula
# cancels catastrophically there) while all others keep a relative error of about 1e-12.
_CANCELLATION_GUARD = 1e-4


def _as_series(x: ArrayLike, name: str) -> np.ndarray:
    """Validates one series as a finite float array of shape ``(n_steps, n_dims)``."""
    arr = np.asarray(x, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[0] == 0 or arr.shape[1] == 0:
        raise ImitateError(
            f"{name} must be a non-empty array of shape (n_steps, n_dims) or (n_steps,); "
            f"got shape {np.shape(x)}"
        )
    if not np.all(np.isfinite(arr)):
        bad = np.argwhere(~np.isfinite(arr))[0]
        raise ImitateError(
            f"{name} contains a non-finite value ({arr[tuple(bad)]}) at step {bad[0]}, "
            f"dimension {bad[1]}; interpolate or drop missing samples first"
        )
    return arr


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
    a = _as_series(a, "a")
    b = _as_series(b, "b")
    if a.shape[1] != b.shape[1]:
        raise ImitateError(
            f"a and b must have the same number of dimensions; got {a.shape[1]} and {b.shape[1]}"
        )
    w = _as_weights(weights, a.shape[1])
    return _local_costs(a * w, b * w)


def _local_costs(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Euclidean distances between the rows of already scaled ``a`` (n, d) and ``b`` (m, d)."""
    centre = 0.5 * (a.mean(axis=0) + b.mean(axis=0))
    a = a - centre
    b = b - centre
    aa = np.einsum("ij,ij->i", a, a)
    bb = np.einsum("ij,ij->i", b, b)
    d2 = a @ (-2.0 * b).T
    d2 += aa[:, None]
    d2 += bb
    guard = _CANCELLATION_GUARD * (aa.max() + bb.max())
    if d2.min() < guard:
        ii, jj = np.nonzero(d2 < guard)
        diff = a[ii] - b[jj]
        d2[ii, jj] = np.einsum("ij,ij->i", diff, diff)
    return np.sqrt(d2, out=d2)


def _accumulate(v: np.ndarray) -> np.ndarray:
    """Accumulated cost of eq. 2, one anti-diagonal at a time, for one or a stack of pairs.

    Args:
        v: Local costs, C-contiguous, shape ``(n, m)`` or ``(n, m, n_pairs)``, finite.

    Returns:
        The table in skewed layout, shape ``(n + m - 1, n + 1[, n_pairs])``: the eq. 2 value of
        cell ``(i, j)`` is at ``[i + j, i + 1]``. Column 0 and the entry just past each
        anti-diagonal hold ``inf`` (eq. 2's border); other entries outside the grid are never
        read. Cells beyond a pair's true size do not influence the cells before them, so pairs of
        different sizes can share one zero-padded stack.
    """
    n, m = v.shape[:2]
    step = v.strides[1]
    # Skewed view without copying: element [k, i] is v[i, k - i]; offsets stay inside v's buffer.
    v_diag = as_strided(
        v, shape=(n + m - 1, n) + v.shape[2:], strides=(step, (m - 1) * step) + v.strides[2:],
        writeable=False,
    )
    acc = np.empty((n + m - 1, n + 1) + v.shape[2:])
    acc[:, 0] = np.inf
    k = np.arange(n + m - 1)
    past = np.minimum(k, n - 1) + 2
    inside = past <= n
    acc[k[inside], past[inside]] = np.inf
    acc[0, 1] = v[0, 0]
    tmp = np.empty((n,) + v.shape[2:])
    rows = list(acc)
    v_rows = list(v_diag)
    for k in range(1, n + m - 1):
        lo = k - m + 1 if k >= m else 0
        hi = k + 1 if k < n else n
        prev = rows[k - 1]
        t = tmp[lo:hi]
        np.minimum(prev[lo:hi], prev[lo + 1 : hi + 1], out=t)  # up (i-1, j), left (i, j-1)
        if k >= 2:
            np.minimum(t, rows[k - 2][lo:hi], out=t)  # diagonal (i-1, j-1)
        np.add(t, v_rows[k][lo:hi], out=rows[k][lo + 1 : hi + 1])
    return acc


def _backtrack(acc: np.ndarray, n: int, m: int) -> np.ndarray:
    """Optimal path from ``(n-1, m-1)`` back to ``(0, 0)`` through one skewed table (2-D)."""
    width = acc.shape[1]
    flat = memoryview(np.ascontiguousarray(acc).ravel())
    i, j = n - 1, m - 1
    rows = [i]
    cols = [j]
    while i > 0 or j > 0:
        if i == 0:
            j -= 1
        elif j == 0:
            i -= 1
        else:
            prev = (i + j - 1) * width
            diag = flat[prev - width + i]
            left = flat[prev + i + 1]
            up = flat[prev + i]
            if diag <= left and diag <= up:
                i -= 1
                j -= 1
            elif left <= up:
                j -= 1
            else:
                i -= 1
        rows.append(i)
        cols.append(j)
    return np.column_stack((rows[::-1], cols[::-1])).astype(np.intp)


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
    v = local_costs(a, b, weights)
    n, m = v.shape
    acc = _accumulate(v)
    return float(acc[n + m - 2, n]), _backtrack(acc, n, m)


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

    All pairwise DTW problems are solved together in one vectorised sweep. The reference is the
    medoid (the demonstration with the smallest summed DTW distance to the others, lowest index on
    ties) unless given.

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
    lengths = [s.shape[0] for s in series]

    pairs = [(p, q) for p in range(n_demos) for q in range(p + 1, n_demos)]
    n_max = max(lengths)
    v = np.zeros((n_max, n_max, len(pairs)))
    for k, (p, q) in enumerate(pairs):
        v[: lengths[p], : lengths[q], k] = _local_costs(scaled[p], scaled[q])
    acc = _accumulate(v)

    distances = np.zeros((n_demos, n_demos))
    for k, (p, q) in enumerate(pairs):
        distances[p, q] = distances[q, p] = acc[lengths[p] + lengths[q] - 2, lengths[p], k]
    if reference is None:
        reference = int(np.argmin(distances.sum(axis=1)))

    n_ref = lengths[reference]
    paths = []
    aligned = np.empty((n_demos, n_ref, n_dims))
    for d in range(n_demos):
        if d == reference:
            path = np.column_stack((np.arange(n_ref), np.arange(n_ref)))
        else:
            k = pairs.index((min(d, reference), max(d, reference)))
            path = _backtrack(acc[:, :, k], lengths[min(d, reference)], lengths[max(d, reference)])
            if d > reference:
                path = path[:, ::-1]
        paths.append(path)
        aligned[d] = warp_to_reference(series[d], path, n_ref)
    return Alignment(
        aligned=aligned, reference=reference, paths=tuple(paths), distances=distances, weights=w
    )
