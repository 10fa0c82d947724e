"""The rim correction of an object's ends, compiled (numba): step 5 of the tracker.

A rim's extreme point in an image is not its centre. With an estimate of the bottom and top
centres, the rims (circles of the object's end radii) are projected into both views, their
extremes along each view's axis line predicted, the observed extremes shifted back by how far
those lie beyond the projected centres, and the ends re-triangulated. Cameras are passed as
arrays: ``intrinsics (2, 3, 3)``, world-to-camera ``rotations (2, 3, 3)``, ``positions (2, 3)``.

The vector arithmetic is written as element loops, not NumPy array expressions: the same
arithmetic, without compiling numba's shape checks (whose error messages alone cost seconds of
compilation); the matrix and dot products stay NumPy's.
"""

from __future__ import annotations

import numba
import numpy as np

from imitate._numba import ensure_writable

ensure_writable(__file__)  # before the kernels below are declared

_RIM_POINTS = 24
_RIM_PHASES = np.linspace(0.0, 2 * np.pi, _RIM_POINTS, endpoint=False)
_RIM_COS, _RIM_SIN = np.cos(_RIM_PHASES), np.sin(_RIM_PHASES)


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _project(intrinsics, rotation, position, point) -> tuple[float, float]:
    """Pixel ``(col, row)`` of world ``point (3,)`` [m]; as ``PinholeCamera.project``."""
    rel = np.empty(3)
    for e in range(3):
        rel[e] = point[e] - position[e]
    cam = rotation @ rel
    pix = intrinsics @ cam
    return pix[0] / pix[2], pix[1] / pix[2]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _triangulate_pair(intrinsics, rotations, positions, pl, pr) -> np.ndarray:
    """World point ``(3,)`` [m] of pixels ``pl (2,)`` (camera 0) and ``pr (2,)`` (camera 1);
    as ``camera.triangulate``, with cameras given as in :func:`_correct_ends`."""
    rays = np.empty((2, 3))
    for c, pix in enumerate((pl, pr)):
        k, r = intrinsics[c], rotations[c]
        x = (pix[0] - k[0, 2]) / k[0, 0]
        y = (pix[1] - k[1, 2]) / k[1, 1]
        for q in range(3):
            rays[c, q] = x * r[0, q] + y * r[1, q] + r[2, q]
    d1, d2 = rays[0], rays[1]
    w0 = np.empty(3)
    for q in range(3):
        w0[q] = positions[0, q] - positions[1, q]
    a, b, c = d1 @ d1, d1 @ d2, d2 @ d2
    d, e = d1 @ w0, d2 @ w0
    denom = a * c - b * b
    t1, t2 = (b * e - c * d) / denom, (a * e - b * d) / denom
    point = np.empty(3)
    for q in range(3):
        point[q] = 0.5 * (positions[0, q] + t1 * d1[q] + positions[1, q] + t2 * d2[q])
    return point


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _rim_fit(ends, radii, intrinsics, rotations, positions, origins, directions, extents):
    """How the rims of ``ends`` appear in the two views, against the views' measurements.

    Per view, the extreme points along the view's axis line of the two rims (circles of
    ``_RIM_POINTS`` points) are predicted, and the observed extremes shifted back by how far
    those lie beyond the projected rim centres.

    Args:
        ends: ``(2, 3)`` bottom and top centres [m].
        radii: ``(2,)`` bottom and top rim radii [m].
        intrinsics: ``(2, 3, 3)`` left and right ``K`` [px].
        rotations: ``(2, 3, 3)`` left and right world-to-camera rotations.
        positions: ``(2, 3)`` left and right optical centres [m].
        origins: ``(2, 2)`` per view (left, right) a point of the axis line [px].
        directions: ``(2, 2)`` per view the line's unit direction, bottom to top.
        extents: ``(2, 2)`` per view the observed extremes along the line from its origin [px]
            (as in :class:`imitate.perception.tracker.ViewMeasurement`).

    Returns:
        ``(shifted (2, 2, 2) [px] (view, end, (col, row)), misfit [px^2])``: the shifted
        extremes, and the summed squares of the predicted extremes' offsets from the observed
        ones along the lines and of the projected centres' distances from the lines (inf for
        a degenerate axis).
    """
    axis = np.empty(3)
    for e in range(3):
        axis[e] = ends[1, e] - ends[0, e]
    length = np.sqrt(axis @ axis)
    a = np.empty(3)
    for e in range(3):
        a[e] = axis[e] / length
    # u: a unit vector perpendicular to a (a x e for the basis vector e least aligned with a);
    # v = a x u.
    u = np.empty(3)
    if abs(a[0]) < 0.9:
        u[0], u[1], u[2] = 0.0, a[2], -a[1]
    else:
        u[0], u[1], u[2] = -a[2], 0.0, a[0]
    length = np.sqrt(u @ u)
    for e in range(3):
        u[e] /= length
    v = np.empty(3)
    v[0] = a[1] * u[2] - a[2] * u[1]
    v[1] = a[2] * u[0] - a[0] * u[2]
    v[2] = a[0] * u[1] - a[1] * u[0]
    rim = np.empty(3)
    shifted = np.empty((2, 2, 2))
    misfit = 0.0
    for c in range(2):
        k, r, p = intrinsics[c], rotations[c], positions[c]
        o, d = origins[c], directions[c]
        for j in range(2):
            col, row = _project(k, r, p, ends[j])
            along = (col - o[0]) * d[0] + (row - o[1]) * d[1]
            across = -(col - o[0]) * d[1] + (row - o[1]) * d[0]
            # The rim's extreme point: lowest along the line for the bottom, highest for the top.
            extreme = np.inf if j == 0 else -np.inf
            for q in range(_RIM_POINTS):
                for e in range(3):
                    rim[e] = ends[j, e] + radii[j] * (_RIM_COS[q] * u[e] + _RIM_SIN[q] * v[e])
                pc, pr = _project(k, r, p, rim)
                s = (pc - o[0]) * d[0] + (pr - o[1]) * d[1]
                extreme = min(extreme, s) if j == 0 else max(extreme, s)
            misfit += (extreme - extents[c, j]) ** 2 + across**2
            shift = extents[c, j] - (extreme - along)
            for e in range(2):
                shifted[c, j, e] = o[e] + shift * d[e]
    return shifted, misfit if misfit < np.inf else np.inf  # NaN: a degenerate axis


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _refine(
    ends, radii, intrinsics, rotations, positions, origins, directions, extents, iterations
):
    """Rim-extreme correction of the ends, from ``ends``.

    Per iteration, the observed extremes shifted back by the rims' predicted offsets
    (:func:`_rim_fit`) are re-triangulated.

    Args:
        ends: ``(2, 3)`` start bottom and top centres [m].
        radii: ``(2,)`` bottom and top rim radii [m].
        intrinsics: ``(2, 3, 3)`` left and right ``K`` [px].
        rotations: ``(2, 3, 3)`` left and right world-to-camera rotations.
        positions: ``(2, 3)`` left and right optical centres [m].
        origins: ``(2, 2)`` per view a point of the axis line [px].
        directions: ``(2, 2)`` per view the line's unit direction, bottom to top.
        extents: ``(2, 2)`` per view the observed extremes along the line from its origin [px].
        iterations: corrections applied.

    Returns:
        ``(ends (2, 3) [m], misfit [px^2])``: the corrected ends and their misfit to the views
        (:func:`_rim_fit`).
    """
    args = (radii, intrinsics, rotations, positions, origins, directions, extents)
    ends = ends.copy()
    for _ in range(iterations):
        shifted, _misfit = _rim_fit(ends, *args)
        for j in range(2):
            point = _triangulate_pair(
                intrinsics, rotations, positions, shifted[0, j], shifted[1, j]
            )
            for e in range(3):
                ends[j, e] = point[e]
    return ends, _rim_fit(ends, *args)[1]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def _correct_ends(
    raw, eyes, radii, intrinsics, rotations, positions, origins, directions, extents, iterations
):
    """Ends ``(2, 3)`` [m] corrected for the rims' extremes, from the triangulated extremes.

    The correction has two fixed points, the axis tilted towards or away from the eyes by
    about the same angle (an object lying across the view); it starts from ``raw`` and from
    ``raw`` with its axis mirrored in the plane normal to the line of sight, and keeps the
    result whose predicted extremes and centres fit both views better.

    Args:
        raw: ``(2, 3)`` triangulated bottom and top extremes [m].
        eyes: ``(3,)`` the point between the optical centres [m].
        radii: ``(2,)`` bottom and top rim radii [m].
        intrinsics: ``(2, 3, 3)`` left and right ``K`` [px].
        rotations: ``(2, 3, 3)`` left and right world-to-camera rotations.
        positions: ``(2, 3)`` left and right optical centres [m].
        origins: ``(2, 2)`` per view a point of the axis line [px].
        directions: ``(2, 2)`` per view the line's unit direction, bottom to top.
        extents: ``(2, 2)`` per view the extremes along the line from its origin [px].
        iterations: corrections per start.

    Returns:
        ``(2, 3)`` bottom and top centres [m]; NaN for a degenerate axis.
    """
    mid, axis, view = np.empty(3), np.empty(3), np.empty(3)
    for e in range(3):
        mid[e] = 0.5 * (raw[0, e] + raw[1, e])
        axis[e] = raw[1, e] - raw[0, e]
        view[e] = mid[e] - eyes[e]
    length = np.sqrt(view @ view)
    sight = np.empty(3)
    for e in range(3):
        sight[e] = view[e] / length
    along = 2 * (axis @ sight)
    mirrored = np.empty((2, 3))
    for e in range(3):
        axis[e] = axis[e] - along * sight[e]
        mirrored[0, e] = mid[e] - 0.5 * axis[e]
        mirrored[1, e] = mid[e] + 0.5 * axis[e]
    args = (radii, intrinsics, rotations, positions, origins, directions, extents, iterations)
    ends, misfit = _refine(raw, *args)
    other, other_misfit = _refine(mirrored, *args)
    return other if other_misfit < misfit else ends
