"""The tracker's loops over a silhouette's outline, compiled (numba): steps 3-4 of the tracker.

The outline is the silhouette's outer contour, ``(n, 2)`` float pixels ``(col, row)``.
"""

from __future__ import annotations

import numba
import numpy as np

from imitate._numba import ensure_writable

ensure_writable(__file__)  # before the kernels below are declared


@numba.njit(cache=True, nogil=True)
def _extremes(outline: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Sub-pixel extremes ``(2,)`` of the ``outline (n, 2)`` along the line ``origin (2,)``,
    ``direction (2,)`` [px, from ``origin``].

    The mean over the outline pixels within one pixel of each extreme: an end edge spans
    several pixels, and their mean moves smoothly with the edge where the single extreme pixel
    jumps by whole pixels (one pixel of disparity is 2 cm of depth at 1.1 m).
    """
    n = outline.shape[0]
    along = np.empty(n)
    for i in range(n):
        along[i] = (outline[i, 0] - origin[0]) * direction[0] + (
            outline[i, 1] - origin[1]
        ) * direction[1]
    low, high = _min_max(along)
    sum_low = sum_high = 0.0
    n_low = n_high = 0
    for a in along:
        if a < low + 1.0:
            sum_low += a
            n_low += 1
        if a > high - 1.0:
            sum_high += a
            n_high += 1
    extent = np.empty(2)
    extent[0], extent[1] = sum_low / n_low, sum_high / n_high
    return extent


# The kernels below use element loops and scalars where NumPy would use array expressions,
# np.interp, np.full or ndarray.min: the same arithmetic, without compiling numba's shape
# checks (whose error messages alone cost seconds of compilation) and its general
# implementations of those functions.


@numba.njit(cache=True, nogil=True)
def _min_max(values: np.ndarray) -> tuple[float, float]:
    """``(values.min(), values.max())`` of finite ``values (n,)``, ``n >= 1``."""
    low = high = values[0]
    for i in range(1, values.shape[0]):
        if values[i] < low:
            low = values[i]
        if values[i] > high:
            high = values[i]
    return low, high


@numba.njit(cache=True, nogil=True)
def _interp(x: float, xp: np.ndarray, fp: np.ndarray) -> float:
    """``np.interp(x, xp, fp)`` for a scalar ``x`` and increasing ``xp (m,)``: numba's (and
    NumPy's) arithmetic, edge cases included."""
    m = xp.shape[0]
    if m == 1:
        return fp[0]
    if np.isnan(x):
        return x
    if x > xp[m - 1]:
        return fp[m - 1]
    if x < xp[0]:
        return fp[0]
    j = 0  # the last j with xp[j] <= x, as NumPy's search finds it
    while j + 1 < m and x >= xp[j + 1]:
        j += 1
    if j == m - 1 or xp[j] == x:
        return fp[j]
    slope = (fp[j + 1] - fp[j]) / (xp[j + 1] - xp[j])
    value = slope * (x - xp[j]) + fp[j]
    if np.isnan(value):  # as NumPy: try from the other end, then a flat segment
        value = slope * (x - xp[j + 1]) + fp[j + 1]
        if np.isnan(value) and fp[j] == fp[j + 1]:
            value = fp[j]
    return value


@numba.njit(cache=True, nogil=True)
def _fit_axis_line(
    outline, origin, direction, heights, radii, px_per_m, occluded, offset, end_zone, min_edges
):
    """Least-squares axis line through the free side edges, one apparent radius inside them.

    Compiled (numba): a loop over the outline, where NumPy's per-call overhead on these small
    arrays was most of the tracker's time.

    Args:
        outline: ``(n, 2)`` float outer contour pixels ``(col, row)`` of the silhouette.
        origin: ``(2,)`` a point of the current axis estimate [px].
        direction: ``(2,)`` its unit direction, bottom to top.
        heights: ``(m,)`` the object's profile heights, increasing from 0 [m].
        radii: ``(m,)`` its radius at those heights [m].
        px_per_m: image scale at the object's depth [px/m].
        occluded: ``(h, w)`` bool occluder mask of the searched window; ``(0, 0)`` for none
            (every edge is then the object's own).
        offset: ``(2,)`` ``(col0, row0)`` of that window in the image.
        end_zone: fraction of the length at either end whose edges are not used.
        min_edges: fewest free edges for a fit.

    Returns:
        ``(origin (2,), direction (2,), number of edge pixels used)``; the number is 0 (and the
        line the given one) with fewer than ``min_edges`` edges or a degenerate fit.
    """
    perp = np.empty(2)
    perp[0], perp[1] = -direction[1], direction[0]
    count = outline.shape[0]
    s_all, x_all = np.empty(count), np.empty(count)
    for i in range(count):
        rx, ry = outline[i, 0] - origin[0], outline[i, 1] - origin[1]
        s_all[i] = rx * direction[0] + ry * direction[1]
        x_all[i] = rx * perp[0] + ry * perp[1]
    low, high = _min_max(s_all)
    # Slices one pixel thick across the axis; each has two edges, its extremes across it.
    n = int(high - low) + 1
    lo, hi = np.empty(n), np.empty(n)
    for k in range(n):
        lo[k], hi[k] = np.inf, -np.inf
    for i in range(count):
        k = int(s_all[i] - low)
        lo[k] = min(lo[k], x_all[i])
        hi[k] = max(hi[k], x_all[i])
    obj_height = heights[-1]
    span = max(high - low, 1e-9)
    # Sums of the normal equations of x = x0 + slope * s over the free edges.
    used, sum_s, sum_x, sum_ss, sum_sx = 0, 0.0, 0.0, 0.0, 0.0
    for side in (-1.0, 1.0):
        for k in range(n):
            if not np.isfinite(lo[k]):
                continue
            s = low + k + 0.5
            x = lo[k] if side < 0 else hi[k]
            height = (s - low) / span * obj_height
            if not (end_zone * obj_height < height < (1 - end_zone) * obj_height):
                continue
            if not side * x > 0:  # a slice narrower than the axis estimate has no usable edge
                continue
            if occluded.shape[0] > 0:
                # An edge whose outside neighbour is an occluder is where something covers the
                # object, not the object's own side.
                out = x + 1.5 * side
                col = int(np.rint(origin[0] + s * direction[0] + out * perp[0] - offset[0]))
                row = int(np.rint(origin[1] + s * direction[1] + out * perp[1] - offset[1]))
                if 0 <= col < occluded.shape[1] and 0 <= row < occluded.shape[0]:
                    if occluded[row, col]:
                        continue
            axis_x = x - side * _interp(height, heights, radii) * px_per_m
            used += 1
            sum_s += s
            sum_x += axis_x
            sum_ss += s * s
            sum_sx += s * axis_x
    if used < min_edges:
        return origin, direction, 0
    det = used * sum_ss - sum_s**2
    if not det > 0:
        return origin, direction, 0
    slope = (used * sum_sx - sum_s * sum_x) / det
    x0 = (sum_x - slope * sum_s) / used
    norm = np.hypot(1.0, slope)
    new_origin, new_direction = np.empty(2), np.empty(2)
    for e in range(2):
        new_origin[e] = origin[e] + x0 * perp[e]
        new_direction[e] = (direction[e] + slope * perp[e]) / norm
    return new_origin, new_direction, used
