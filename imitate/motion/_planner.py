"""The planner's inner loops over the task map and the RMR step, compiled (numba).

:class:`imitate.motion.taskspace.TaskMap` and :mod:`imitate.motion.control` run these once per step
of every rollout and of every backward pass; in NumPy, the call overhead of some forty small array
operations per step was most of the planner's time. Between the kernels, MuJoCo computes the
kinematics and the point Jacobians and their rates.

The kernels use element loops and scalars only (no array expressions, no ``np.linalg``): cheap
to compile.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from imitate._numba import ensure_writable

ensure_writable(__file__)  # before the kernels below are declared

# Points of the task map: the tool's and the target's origin ``o``, then ``o + a`` with ``a``
# each one's long axis (its frame's z axis).
N_POINTS = 4
# A task space's terms as rows of a table: kind, first and second anchor (0 the tool, 1 the
# target, 2.. a place), first column, frame (the held object in whose own frame a relative
# position is, -1 the world). Kinds:
RELATIVE, ANGLES = 0, 1  # p_a - p_b (3 columns); the angle and gaze component of object a (2)
# Rows of a term's entry in the ``framed`` buffer: its frame's axes x, y, z (rows), the
# relative position p in the world, the gaze column g that fixes the frame about its z.
FRAME_ROWS = 5


@numba.njit(cache=True)
def _task_state(xpos, xmat, bodies, terms, gaze, angle_ref, singular_rho2, points, proj, inv, x,
                rows, axes, framed):
    """A task space's state at MuJoCo's kinematics ``xpos (nbody, 3)``, ``xmat (nbody, 9)``,
    and what the Jacobian needs; all outputs are written.

    Args:
        xpos: ``(nbody, 3)`` MuJoCo's body positions (``data.xpos``) [m].
        xmat: ``(nbody, 9)`` MuJoCo's body orientations, row-major rotation matrices
            (``data.xmat``).
        bodies: ``(2 + k,)`` the anchors' body ids: the tool, the target, then the places.
        terms: ``(n_terms, 5)`` the term table (kind, anchor, anchor, first column, frame).
        gaze: ``R_gaze`` ``(3, 3)``, columns right, down, forward.
        angle_ref: ``(2,)`` the angles' reference branches [rad].
        singular_rho2: ``rho^2`` below which an angle is undefined (it is then ``angle_ref``).
        points: ``(4, 3)`` the task map's points (see :data:`N_POINTS`) [m].
        proj: ``(2, 3)`` the axes' gaze coordinates ``p`` (right, down, forward).
        inv: ``(2,)`` ``1 / rho^2`` (0 where the angle is undefined).
        x: ``(m,)`` the task state.
        rows: ``(2, 3)`` the gradients of the two angles with respect to the axes, ``C``'s
            first rows times ``R_gaze^T``: ``(-p_d r + p_r d) / rho^2``.
        axes: ``(2, 3)`` the long axes ``a``.
        framed: ``(n_terms, FRAME_ROWS, 3)`` per relative position in an object's frame, that
            frame's axes, the position in the world and the frame's gaze column (see
            :data:`FRAME_ROWS`); other terms' entries are left as they were.
    """
    angles = np.empty(2)
    for o in range(2):
        b = bodies[o]
        for c in range(3):
            axes[o, c] = xmat[b, 3 * c + 2]
            points[o, c] = xpos[b, c]
            points[2 + o, c] = xpos[b, c] + axes[o, c]
        for c in range(3):
            total = 0.0
            for k in range(3):
                total += xmat[b, 3 * k + 2] * gaze[k, c]
            proj[o, c] = total
    for o in range(2):
        pr, pd = proj[o, 0], proj[o, 1]
        rho2 = pr * pr + pd * pd
        if rho2 > singular_rho2:
            angle = math.atan2(pd, pr)
            angle += 2.0 * math.pi * round((angle_ref[o] - angle) / (2.0 * math.pi))
            s = 1.0 / rho2
        else:  # undefined: the reference, with a zero gradient
            angle = angle_ref[o]
            s = 0.0
        angles[o] = angle
        inv[o] = s
        for c in range(3):
            rows[o, c] = -pd * s * gaze[c, 0] + pr * s * gaze[c, 1]
    for i in range(terms.shape[0]):
        kind, first, second, col = terms[i, 0], terms[i, 1], terms[i, 2], terms[i, 3]
        fo = terms[i, 4]
        if kind == RELATIVE:
            for c in range(3):
                x[col + c] = _anchor(xpos, bodies, points, first, c) - _anchor(
                    xpos, bodies, points, second, c)
            if fo >= 0:  # in the object's own frame: x = E p
                along = proj[fo, 0] ** 2 + proj[fo, 1] ** 2 < singular_rho2
                entry = framed[i]
                for c in range(3):
                    entry[3, c] = x[col + c]
                    entry[4, c] = gaze[c, 0 if along else 2]
                _own_frame(axes[fo], entry[4], entry)
                for k in range(3):
                    x[col + k] = (entry[k, 0] * entry[3, 0] + entry[k, 1] * entry[3, 1]
                                  + entry[k, 2] * entry[3, 2])
        else:
            x[col] = angles[first]
            x[col + 1] = proj[first, 2]


@numba.njit(cache=True)
def _own_frame(a, g, e):
    """An object's own frame (:func:`imitate.taskspace.own_frame`) from its unit axis ``a (3,)``
    and the gaze column ``g (3,)`` that fixes it: rows ``x, y, z`` into ``e[:3]``."""
    ga = g[0] * a[0] + g[1] * a[1] + g[2] * a[2]
    norm = 0.0
    for c in range(3):
        e[0, c] = g[c] - ga * a[c]
        norm += e[0, c] * e[0, c]
    norm = math.sqrt(norm)
    for c in range(3):
        e[0, c] /= norm
        e[2, c] = a[c]
    _cross(a, e[0], e[1])


@numba.njit(cache=True)
def _frame_change(a, g, v, w, out):
    """The derivatives of an object's own frame (rows ``x, y, z`` of :func:`_own_frame`) with
    respect to its axis ``a (3,)``: along ``v (3,)`` into ``out[0] (3, 3)``, and the second
    along ``v`` and ``w (3,)`` into ``out[1] (3, 3)`` (``a`` taken as a free vector).

    With ``u = g - (g . a) a``, ``n = |u|``, ``x = u / n``: ``u_v = -(g . v) a - (g . a) v``,
    ``u_vw = -(g . v) w - (g . w) v``, ``n_v = x . u_v``, ``x_v = (u_v - x n_v) / n``,
    ``n_vw = x_w . u_v + x . u_vw``, ``x_vw = (u_vw - u_v n_w / n - u_w n_v / n - x n_vw
    + 2 x n_v n_w / n) / n``; ``y = a x x``: ``y_v = v x x + a x x_v``, ``y_vw = v x x_w +
    w x x_v + a x x_vw``; ``z = a``: ``z_v = v``, ``z_vw = 0``.
    """
    ga = g[0] * a[0] + g[1] * a[1] + g[2] * a[2]
    gv = g[0] * v[0] + g[1] * v[1] + g[2] * v[2]
    gw = g[0] * w[0] + g[1] * w[1] + g[2] * w[2]
    work = np.empty((7, 3))
    x, u_v, u_w, u_vw = work[0], work[1], work[2], work[3]
    x_v, x_w, x_vw = work[4], work[5], work[6]
    norm = 0.0
    for c in range(3):
        x[c] = g[c] - ga * a[c]
        norm += x[c] * x[c]
    norm = math.sqrt(norm)
    n_v = n_w = 0.0
    for c in range(3):
        x[c] /= norm
        u_v[c] = -gv * a[c] - ga * v[c]
        u_w[c] = -gw * a[c] - ga * w[c]
        u_vw[c] = -gv * w[c] - gw * v[c]
        n_v += x[c] * u_v[c]
        n_w += x[c] * u_w[c]
    n_vw = 0.0
    for c in range(3):
        x_v[c] = (u_v[c] - x[c] * n_v) / norm
        x_w[c] = (u_w[c] - x[c] * n_w) / norm
    for c in range(3):
        n_vw += x_w[c] * u_v[c] + x[c] * u_vw[c]
    for c in range(3):
        x_vw[c] = (u_vw[c] - (u_v[c] * n_w + u_w[c] * n_v) / norm - x[c] * n_vw
                   + 2.0 * x[c] * n_v * n_w / norm) / norm
    first, second = out[0], out[1]
    turned = np.empty(3)
    for c in range(3):
        first[0, c] = x_v[c]
        first[2, c] = v[c]
        second[0, c] = x_vw[c]
        second[2, c] = 0.0
    _cross(v, x, first[1])
    _cross(a, x_v, turned)
    for c in range(3):
        first[1, c] += turned[c]
    _cross(v, x_w, second[1])
    _cross(w, x_v, turned)
    for c in range(3):
        second[1, c] += turned[c]
    _cross(a, x_vw, turned)
    for c in range(3):
        second[1, c] += turned[c]


@numba.njit(cache=True)
def _anchor(xpos, bodies, points, anchor, c) -> float:
    """Coordinate ``c`` of an anchor's position: a held object's origin, a place's body."""
    return points[anchor, c] if anchor < 2 else xpos[bodies[anchor], c]


@numba.njit(cache=True)
def _task_jacobian(jac, dof, terms, axes, rows, gaze, framed, mask, J, axis_jac, rot_jac,
                   trans_jac):
    """The task Jacobian ``J (m, n)``, the axes' Jacobians ``axis_jac (2, 3, n)`` (``da/dq``)
    and the objects' rotational and translational Jacobians ``rot_jac``, ``trans_jac (2, 3,
    n)``, all written, from MuJoCo's ``jac (2, 2, 3, nv)`` (per object, translational and
    rotational Jacobian of its origin; the planned joints are the columns ``dof (n,)``);
    ``da/dq_j = omega_j x a``; a place does not move with the joints. ``terms`` is the term
    table and ``framed`` the frames (see :func:`_task_state`); a position ``E p`` in an object's
    frame changes by ``E_A p + E P`` (``A``, ``P`` the changes of the axis and of ``p``).
    Columns where ``mask (n,)`` is 0 are 0 in ``J``."""
    n = dof.shape[0]
    change = np.empty((2, 3, 3))
    moved = np.empty(3)
    for j in range(n):
        col = dof[j]
        for o in range(2):
            r0, r1, r2 = jac[o, 1, 0, col], jac[o, 1, 1, col], jac[o, 1, 2, col]
            a0, a1, a2 = axes[o, 0], axes[o, 1], axes[o, 2]
            rot_jac[o, 0, j], rot_jac[o, 1, j], rot_jac[o, 2, j] = r0, r1, r2
            for c in range(3):
                trans_jac[o, c, j] = jac[o, 0, c, col]
            axis_jac[o, 0, j] = r1 * a2 - r2 * a1
            axis_jac[o, 1, j] = r2 * a0 - r0 * a2
            axis_jac[o, 2, j] = r0 * a1 - r1 * a0
        for i in range(terms.shape[0]):
            kind, first, second, row = terms[i, 0], terms[i, 1], terms[i, 2], terms[i, 3]
            fo = terms[i, 4]
            if kind == RELATIVE:
                for c in range(3):
                    moved[c] = _moved(jac, first, c, col) - _moved(jac, second, c, col)
                if fo < 0:
                    for c in range(3):
                        J[row + c, j] = moved[c] * mask[j]
                    continue
                entry = framed[i]
                _frame_change(axes[fo], entry[4], axis_jac[fo, :, j], axis_jac[fo, :, j], change)
                for k in range(3):
                    total = 0.0
                    for c in range(3):
                        total += change[0, k, c] * entry[3, c] + entry[k, c] * moved[c]
                    J[row + k, j] = total * mask[j]
            else:
                da0, da1, da2 = axis_jac[first, 0, j], axis_jac[first, 1, j], axis_jac[first, 2, j]
                J[row, j] = (rows[first, 0] * da0 + rows[first, 1] * da1
                             + rows[first, 2] * da2) * mask[j]
                J[row + 1, j] = (gaze[0, 2] * da0 + gaze[1, 2] * da1 + gaze[2, 2] * da2) * mask[j]


@numba.njit(cache=True)
def _moved(jac, anchor, c, col) -> float:
    """Row ``c``, column ``col`` of an anchor's translational Jacobian (0 for a place)."""
    return jac[anchor, 0, c, col] if anchor < 2 else 0.0


@numba.njit(cache=True)
def _translated(trans_jac, anchor, c, j) -> float:
    """Row ``c``, column ``j`` of an anchor's translational Jacobian ``trans_jac (2, 3, n)``
    (0 for a place)."""
    return trans_jac[anchor, c, j] if anchor < 2 else 0.0


@numba.njit(cache=True)
def _cross(u, v, out):
    """``out = u x v`` for ``(3,)`` vectors."""
    out[0] = u[1] * v[2] - u[2] * v[1]
    out[1] = u[2] * v[0] - u[0] * v[2]
    out[2] = u[0] * v[1] - u[1] * v[0]


@numba.njit(cache=True)
def _curvature(a, b, c, d, rates, dof, terms, axes, rows, proj, inv, axis_jac, rot_jac,
               trans_jac, framed, gaze, mask, out):
    """``a^T D_b J + c^T D_d J`` into ``out (n,)`` (see :meth:`TaskMap.curvature`).

    Args:
        a: ``(m,)`` task vector contracted with ``D_b J``.
        b: ``(n,)`` joint direction [rad].
        c: ``(m,)`` task vector contracted with ``D_d J``.
        d: ``(n,)`` joint direction [rad].
        rates: ``(2, 2, 2, 3, nv)`` per direction (``b``, ``d``) and object, the derivatives of
            its origin's translational and rotational Jacobian (columns ``dof (n,)``).
        dof: ``(n,)`` the planned joints' columns in MuJoCo's ``nv`` Jacobian columns.
        terms: ``(n_terms, 4)`` the term table (see :func:`_task_state`).
        axes: ``(2, 3)`` the long axes ``a`` (task frame, see :class:`TaskFrame`).
        rows: ``(2, 3)`` the angles' gradients with respect to the axes (task frame).
        proj: ``(2, 3)`` the axes' gaze coordinates ``p`` (task frame).
        inv: ``(2,)`` ``1 / rho^2``, 0 where the angle is undefined (task frame).
        axis_jac: ``(2, 3, n)`` ``da/dq`` (task frame).
        rot_jac: ``(2, 3, n)`` the objects' rotational Jacobians (task frame).
        trans_jac: ``(2, 3, n)`` the objects' translational Jacobians (task frame).
        framed: the frames of the positions in an object's frame (see :func:`_task_state`).
        gaze: ``R_gaze`` ``(3, 3)``, columns right, down, forward.
        mask: ``(n,)`` 1 for a driven joint, 0 for a fixed one, as in :func:`_task_jacobian`.
        out: ``(n,)`` output, written.

    With ``A = omega x a`` per joint, ``D_b A = omega' x a + omega x a'`` and ``a' = A b``; a
    row ``w`` of ``C R_gaze^T`` weighs it as ``w . (omega' x a) = omega' . (a x w)`` and
    ``w . (omega x a') = omega . (a' x w)``. An object without angles has ``w = 0``.

    A position ``E p`` in an object's frame (:func:`_frame_change`'s ``E_v``, ``E_vw``), row
    ``j`` of ``D_b J`` weighed by ``v``: ``v . (E_{A_j a'} p + E_{D_b A_j} p + E_{A_j} p' +
    E_{a'} P_j + E D_b P_j)`` with ``a' = A b``, ``p' = P b``; the first three are linear in
    ``A_j`` and ``D_b A_j = omega'_j x a + omega_j x a'``, so they are dot products with
    vectors found once (``L`` by the basis vectors, then ``a x L``, ``a' x L``).
    """
    n = out.shape[0]
    w = np.empty(3)
    moved = np.empty(3)
    across = np.empty((2, 2, 2, 3))  # direction, object, (a x w, a' x w)
    coef = np.zeros((2, 3))  # C' (the angle rows' own derivative): per object, on A's rows
    weights = np.zeros((2, 2, 2))  # direction, object, (angle row, gaze row) of the vector
    for i in range(terms.shape[0]):
        if terms[i, 0] == ANGLES:
            for k in range(2):
                vector = a if k == 0 else c
                weights[k, terms[i, 1], 0] += vector[terms[i, 3]]
                weights[k, terms[i, 1], 1] += vector[terms[i, 3] + 1]
    for k in range(2):
        direction = b if k == 0 else d
        for o in range(2):
            for e in range(3):
                w[e] = weights[k, o, 0] * rows[o, e] + weights[k, o, 1] * gaze[e, 2]
                total = 0.0
                for j in range(n):
                    total += axis_jac[o, e, j] * direction[j]
                moved[e] = total  # a' = A direction
            _cross(axes[o], w, across[k, o, 0])
            _cross(moved, w, across[k, o, 1])
            # C': d(-p_d s, p_r s) with s = 1 / rho^2 and p' = R^T a'.
            pr, pd, s = proj[o, 0], proj[o, 1], inv[o]
            dpr = gaze[0, 0] * moved[0] + gaze[1, 0] * moved[1] + gaze[2, 0] * moved[2]
            dpd = gaze[0, 1] * moved[0] + gaze[1, 1] * moved[1] + gaze[2, 1] * moved[2]
            ds = -2.0 * (pr * dpr + pd * dpd) * s * s
            weight = weights[k, o, 0]
            cr = weight * (-dpd * s - pd * ds)
            cd = weight * (dpr * s + pr * ds)
            for e in range(3):
                coef[o, e] += cr * gaze[e, 0] + cd * gaze[e, 1]
    weighed = _framed_weights(a, b, c, d, terms, axes, axis_jac, trans_jac, framed)
    for j in range(n):
        col = dof[j]
        total = 0.0
        for k in range(2):
            vector = a if k == 0 else c
            for i in range(terms.shape[0]):
                if terms[i, 0] == RELATIVE:
                    first, second, row = terms[i, 1], terms[i, 2], terms[i, 3]
                    fo, wf = terms[i, 4], weighed[k, i]
                    for e in range(3):
                        shift = _moved(rates[k], first, e, col) - _moved(rates[k], second, e, col)
                        if fo < 0:
                            total += vector[row + e] * shift
                            continue
                        step = (_translated(trans_jac, first, e, j)
                                - _translated(trans_jac, second, e, j))
                        total += (wf[0, e] * rates[k, fo, 1, e, col] + wf[1, e] * rot_jac[fo, e, j]
                                  + wf[2, e] * axis_jac[fo, e, j] + wf[3, e] * shift
                                  + wf[4, e] * step)
            for o in range(2):
                for e in range(3):
                    total += across[k, o, 0, e] * rates[k, o, 1, e, col]
                    total += across[k, o, 1, e] * rot_jac[o, e, j]
        for o in range(2):
            for e in range(3):
                total += coef[o, e] * axis_jac[o, e, j]
        out[j] = total * mask[j]


@numba.njit(cache=True)
def _framed_weights(a, b, c, d, terms, axes, axis_jac, trans_jac, framed):
    """Per direction (``b`` with ``a``, ``d`` with ``c``) and position in an object's frame, the
    vectors ``(2, n_terms, 5, 3)`` that :func:`_curvature` dots with ``omega'_j``, ``omega_j``,
    ``A_j``, ``D_b P_j`` and ``P_j``: ``a x L``, ``a' x L``, ``M``, ``E^T v``, ``E_{a'}^T v``,
    with ``L_e = v . E_e p`` and ``M_e = v . (E_e p' + E_{e a'} p)`` for the basis vectors
    ``e`` (zero for other terms)."""
    n = axis_jac.shape[2]
    weighed = np.zeros((2, terms.shape[0], 5, 3))
    change = np.empty((2, 3, 3))
    basis = np.zeros(3)
    moved, shifted, lin, both = np.empty(3), np.empty(3), np.empty(3), np.empty(3)  # a', p', L, M
    for k in range(2):
        vector, direction = (a, b) if k == 0 else (c, d)
        for i in range(terms.shape[0]):
            first, second, row, fo = terms[i, 1], terms[i, 2], terms[i, 3], terms[i, 4]
            if terms[i, 0] != RELATIVE or fo < 0:
                continue
            entry, wf = framed[i], weighed[k, i]
            for e in range(3):
                moved[e] = 0.0  # a' = A direction
                shifted[e] = 0.0  # p' = P direction
                for j in range(n):
                    moved[e] += axis_jac[fo, e, j] * direction[j]
                    shifted[e] += (_translated(trans_jac, first, e, j)
                                   - _translated(trans_jac, second, e, j)) * direction[j]
            for e in range(3):
                basis[:] = 0.0
                basis[e] = 1.0
                _frame_change(axes[fo], entry[4], basis, moved, change)
                lin[e] = both[e] = 0.0
                for r in range(3):
                    for q in range(3):
                        lin[e] += vector[row + r] * change[0, r, q] * entry[3, q]
                        both[e] += vector[row + r] * (change[0, r, q] * shifted[q]
                                                      + change[1, r, q] * entry[3, q])
            _cross(axes[fo], lin, wf[0])
            _cross(moved, lin, wf[1])
            _frame_change(axes[fo], entry[4], moved, moved, change)
            for e in range(3):
                wf[2, e] = both[e]
                for r in range(3):
                    wf[3, e] += vector[row + r] * entry[r, e]
                    wf[4, e] += vector[row + r] * change[0, r, e]
    return weighed


@numba.njit(cache=True)
def _rmr_step(t, J, xs, targets, qs, winv, damping, gain, low, high, scale, pushes, lower,
              upper, jac, pinvs, solveds, nullspace_grads, unclippeds):
    """Step ``t`` of an RMR rollout (see :mod:`imitate.motion.control`), the rollout's arrays
    indexed here: from ``q = qs[t] (n,)`` with ``J (m, n)`` and ``x = xs[t] (m,)`` at ``q``
    towards ``target = targets[t + 1] (m,)``; writes ``jac[t] = J``, ``pinvs[t] (n, m)``
    ``J^#``, ``solveds[t] (m,)`` ``(J W^-1 J^T + lambda I)^-1 (target - x + gain J W^-1 g)``,
    ``nullspace_grads[t] (n,)`` ``g = dH/dq - push`` (``push = pushes[t]``), ``unclippeds[t]
    (n,)`` and ``qs[t + 1] (n,)``: the step is ``W^-1 J^T solved - gain W^-1 g``. Returns the
    step's largest joint change ``max |qs[t + 1] - q|`` [rad].

    ``damping`` > 0 and ``winv >= 0`` make the system positive definite: it is solved by
    Cholesky. ``low``, ``high``, ``scale`` are the joint-limit cost's borders and scales,
    ``lower``, ``upper`` the joint ranges.
    """
    x, target, q, q_next, push = xs[t], targets[t + 1], qs[t], qs[t + 1], pushes[t]
    pinv, solved = pinvs[t], solveds[t]
    nullspace_grad, unclipped = nullspace_grads[t], unclippeds[t]
    jac[t] = J
    m, n = J.shape
    JW = np.empty((m, n))
    for i in range(m):
        for j in range(n):
            JW[i, j] = J[i, j] * winv[j]
    chol = np.zeros((m, m))
    for i in range(m):
        for k in range(i + 1):
            total = damping if i == k else 0.0
            for j in range(n):
                total += JW[i, j] * J[k, j]
            for e in range(k):
                total -= chol[i, e] * chol[k, e]
            chol[i, k] = math.sqrt(total) if i == k else total / chol[k, k]
    # Solve L L^T y = r for the columns r of [JW | target - x].
    sol = np.empty((m, n + 1))
    for col in range(n + 1):
        for i in range(m):
            total = JW[i, col] if col < n else target[i] - x[i]
            for e in range(i):
                total -= chol[i, e] * sol[e, col]
            sol[i, col] = total / chol[i, i]
        for i in range(m - 1, -1, -1):
            total = sol[i, col]
            for e in range(i + 1, m):
                total -= chol[e, i] * sol[e, col]
            sol[i, col] = total / chol[i, i]
    for j in range(n):
        excess = min(q[j] - low[j], 0.0) + max(q[j] - high[j], 0.0)
        nullspace_grad[j] = scale[j] * excess - push[j]
    for i in range(m):
        # The null-space step's task part: M^-1 J W^-1 g = (J^#)^T g.
        total = 0.0
        for j in range(n):
            total += sol[i, j] * nullspace_grad[j]
        solved[i] = sol[i, n] + gain * total
        for j in range(n):
            pinv[j, i] = sol[i, j]
    largest = 0.0
    for j in range(n):
        total = 0.0
        for i in range(m):
            total += JW[i, j] * solved[i]
        unclipped[j] = q[j] + total - gain * winv[j] * nullspace_grad[j]
        q_next[j] = min(max(unclipped[j], lower[j]), upper[j])
        largest = max(largest, abs(q_next[j] - q[j]))
    return largest


@numba.njit(cache=True)
def _adjoint_directions(t, lam, clipped_at, pinvs, jacs, solveds, winv, nullspace_steps, p, ln,
                        b, d, dx):
    """The backward pass's products at step ``t`` of a rollout (its arrays indexed here):
    ``lam`` zeroed at the joints ``clipped_at[t]``, then ``p = lam J^#``, ``ln = lam - p J``,
    ``b = W^-1 (lam - J^T p)`` and ``d = W^-1 J^T u - s`` (``J^# = pinvs[t]``, ``J =
    jacs[t]``, ``u = solveds[t]``, ``s = nullspace_steps[t]``, the null-space step's ``gain
    W^-1 g``), all written; ``dx[t + 1] += p``."""
    pinv, J, solved, step, row = pinvs[t], jacs[t], solveds[t], nullspace_steps[t], dx[t + 1]
    n, m = pinv.shape
    for j in range(n):
        if clipped_at[t, j]:
            lam[j] = 0.0
    for i in range(m):
        total = 0.0
        for j in range(n):
            total += lam[j] * pinv[j, i]
        p[i] = total
        row[i] += total
    for j in range(n):
        jp = 0.0
        ju = 0.0
        for i in range(m):
            jp += J[i, j] * p[i]
            ju += J[i, j] * solved[i]
        ln[j] = lam[j] - jp
        b[j] = winv[j] * ln[j]
        d[j] = winv[j] * ju - step[j]


@numba.njit(cache=True)
def _segment_distance(p, u, h, q, v, k) -> float:
    """Distance between the segments ``p + s u`` and ``q + t v``, ``|s| <= h``, ``|t| <= k``
    (centres ``(3,)``, unit directions ``(3,)``, half-lengths; Ericson's closest points)."""
    r0 = p[0] - h * u[0] - q[0] + k * v[0]
    r1 = p[1] - h * u[1] - q[1] + k * v[1]
    r2 = p[2] - h * u[2] - q[2] + k * v[2]
    a = 4.0 * h * h  # |d1|^2 of the segment d1 = 2 h u from p - h u
    e = 4.0 * k * k
    f = 2.0 * k * (v[0] * r0 + v[1] * r1 + v[2] * r2)
    s = 0.0
    t = 0.0
    if a <= 1e-20 and e <= 1e-20:
        pass
    elif a <= 1e-20:
        t = min(max(f / e, 0.0), 1.0)
    else:
        c = 2.0 * h * (u[0] * r0 + u[1] * r1 + u[2] * r2)
        if e <= 1e-20:
            s = min(max(-c / a, 0.0), 1.0)
        else:
            b = 4.0 * h * k * (u[0] * v[0] + u[1] * v[1] + u[2] * v[2])
            denom = a * e - b * b
            if denom > 0.0:
                s = min(max((b * f - c * e) / denom, 0.0), 1.0)
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = min(max(-c / a, 0.0), 1.0)
            elif t > 1.0:
                t = 1.0
                s = min(max((b - c) / a, 0.0), 1.0)
    total = 0.0
    for i, ri in enumerate((r0, r1, r2)):
        gap = ri + 2.0 * h * s * u[i] - 2.0 * k * t * v[i]
        total += gap * gap
    return math.sqrt(total)


@numba.njit(cache=True)
def _near_pairs(geom_xpos, geom_xmat, geom1, geom2, columns, sizes, distmax, out) -> int:
    """The pairs ``(geom1[p], geom2[p])`` whose enclosing capsules and slabs are closer than
    ``distmax``: their indices ``p`` in ``out[:count]``, ascending; returns ``count``.

    Each geom ``g`` lies inside a capsule: the segment of ``sizes[g, 0]`` on either side of its
    centre along its frame's axis ``columns[g, 0]``, grown by ``sizes[g, 1]`` (``inf`` for an
    unbounded geom); and, if ``columns[g, 1] >= 0``, inside the slab of half-thickness
    ``sizes[g, 2]`` across that axis. The distance of two capsules, and the gap between one's
    slab and the other's capsule projected on the slab's normal, are lower bounds of the geoms'
    distance.
    """
    count = 0
    u = np.empty(3)
    v = np.empty(3)
    for p in range(geom1.shape[0]):
        g, h = geom1[p], geom2[p]
        reach = sizes[g, 1] + sizes[h, 1] + distmax
        if not reach < np.inf:
            out[count] = p
            count += 1
            continue
        # The bounding spheres first: cheap, and most pairs are far apart.
        gap = 0.0
        for i in range(3):
            delta = geom_xpos[g, i] - geom_xpos[h, i]
            gap += delta * delta
        if math.sqrt(gap) >= reach + sizes[g, 0] + sizes[h, 0]:
            continue
        for i in range(3):
            u[i] = geom_xmat[g, 3 * i + columns[g, 0]]
            v[i] = geom_xmat[h, 3 * i + columns[h, 0]]
        if _slab_gap(geom_xpos, geom_xmat, g, h, v, columns, sizes) >= distmax:
            continue
        if _slab_gap(geom_xpos, geom_xmat, h, g, u, columns, sizes) >= distmax:
            continue
        if _segment_distance(geom_xpos[g], u, sizes[g, 0], geom_xpos[h], v, sizes[h, 0]) < reach:
            out[count] = p
            count += 1
    return count


@numba.njit(cache=True)
def _slab_gap(geom_xpos, geom_xmat, g, h, v, columns, sizes) -> float:
    """Gap [m] between geom ``g``'s slab and geom ``h``'s capsule (axis ``v (3,)``) along the
    slab's normal; ``-inf`` if ``g`` has no slab (see :func:`_near_pairs`)."""
    column = columns[g, 1]
    if column < 0:
        return -np.inf
    centre = 0.0
    along = 0.0
    for i in range(3):
        normal = geom_xmat[g, 3 * i + column]
        centre += normal * (geom_xpos[h, i] - geom_xpos[g, i])
        along += normal * v[i]
    return abs(centre) - sizes[g, 2] - sizes[h, 0] * abs(along) - sizes[h, 1]


@numba.njit(cache=True)
def _mul_quat(a, b, out):
    """MuJoCo's ``mju_mulQuat``: ``out = a b`` for quaternions ``(4,)`` (w, x, y, z)."""
    out[0] = a[0] * b[0] - a[1] * b[1] - a[2] * b[2] - a[3] * b[3]
    out[1] = a[0] * b[1] + a[1] * b[0] + a[2] * b[3] - a[3] * b[2]
    out[2] = a[0] * b[2] - a[1] * b[3] + a[2] * b[0] + a[3] * b[1]
    out[3] = a[0] * b[3] + a[1] * b[2] - a[2] * b[1] + a[3] * b[0]


@numba.njit(cache=True)
def _rot_vec_quat(v, q, out):
    """MuJoCo's ``mju_rotVecQuat``: ``out = q v q^-1`` for ``v (3,)``, a unit quaternion ``q``."""
    if v[0] == 0.0 and v[1] == 0.0 and v[2] == 0.0:
        out[0], out[1], out[2] = 0.0, 0.0, 0.0
    elif q[0] == 1.0 and q[1] == 0.0 and q[2] == 0.0 and q[3] == 0.0:
        out[0], out[1], out[2] = v[0], v[1], v[2]
    else:
        t0 = q[0] * v[0] + q[2] * v[2] - q[3] * v[1]
        t1 = q[0] * v[1] + q[3] * v[0] - q[1] * v[2]
        t2 = q[0] * v[2] + q[1] * v[1] - q[2] * v[0]
        out[0] = v[0] + 2.0 * (q[2] * t2 - q[3] * t1)
        out[1] = v[1] + 2.0 * (q[3] * t0 - q[1] * t2)
        out[2] = v[2] + 2.0 * (q[1] * t1 - q[2] * t0)


@numba.njit(cache=True)
def _hold(held, weld, qpos, xpos, xquat):
    """Sets each held object's free joint ``qpos`` to its hand's pose ``xpos``, ``xquat``
    composed with the weld's, by MuJoCo's arithmetic (``mju_rotVecQuat``, ``mju_mulQuat``: the
    same bits).

    Args:
        held: ``(k, 2)`` per object: its hand's body and its free joint's qpos address.
        weld: ``(k, 7)`` the object's pose in its hand's frame (position, quaternion).
        qpos: ``(nq,)`` MuJoCo's joint positions, the held objects' free joints written.
        xpos: ``(nbody, 3)`` the bodies' world positions (``data.xpos``) [m].
        xquat: ``(nbody, 4)`` the bodies' world orientations (``data.xquat``), ``w`` first.
    """
    rotated = np.empty(3)
    for o in range(held.shape[0]):
        hand, adr = held[o, 0], held[o, 1]
        _rot_vec_quat(weld[o, :3], xquat[hand], rotated)
        for i in range(3):
            qpos[adr + i] = rotated[i] + xpos[hand, i]
        _mul_quat(xquat[hand], weld[o, 3:], qpos[adr + 3 : adr + 7])


@numba.njit(cache=True)
def _lerp(qa, qb, s, qpos, adr):
    """``qpos[adr] = (1 - s) qa + s qb`` (``(n,)`` each; the same bits as NumPy's)."""
    for i in range(adr.shape[0]):
        qpos[adr[i]] = (1.0 - s) * qa[i] + s * qb[i]


@numba.njit(cache=True)
def _adjoint_update(t, gqs, ln, alpha, winv, hessians, curvature, lam):
    """``lam = gq + ln - alpha (ln W^-1) H'' + curvature`` (all ``(n,)``, ``gq = gqs[t]``,
    ``H'' = hessians[t]``, ``lam`` written): the backward recursion's step at step ``t`` (see
    :func:`imitate.motion.control.backward`)."""
    gq, hessian = gqs[t], hessians[t]
    for j in range(lam.shape[0]):
        lam[j] = gq[j] + ln[j] - alpha * (ln[j] * winv[j]) * hessian[j] + curvature[j]
