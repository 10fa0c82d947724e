r"""A task space on the robot: :class:`TaskMap` maps the joint angles ``q`` through the held
objects (and the places, which the joints do not move).

The task spaces, their columns and the gaze frame are :mod:`imitate.taskspace`'s; the map here
gives ``x`` with ``J = dx/dq`` and its derivatives for the planner. At any posture its value is
the space's map (:class:`imitate.taskspace.TaskSpace`) of the held objects' frames (origin,
``z`` axis) and the places' bodies. Where an
object's axis is along the gaze (below :data:`imitate.taskspace.SINGULAR_TOL`) its angle is
``angle_ref`` with a zero Jacobian row; the ``a . f`` component keeps its exact Jacobian.

Robot-side Jacobians use MuJoCo's conventions: ``jac_pos = dp/dq`` and the rotational Jacobian
maps joint velocities to the world-frame angular velocity ``omega``, so ``da/dq[:, i] =
jac_rot[:, i] x a``; :class:`TaskMap` gets ``da/dq`` as the Jacobian of the point ``o + a``
minus that of the object's origin ``o``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, NamedTuple

import mujoco
import numpy as np
from numpy.typing import ArrayLike

from imitate.errors import ImitateError
from imitate.motion import _planner
from imitate.taskspace import EQ1, OBJECTS, SINGULAR_TOL, Relative, TaskSpace, check_gaze

if TYPE_CHECKING:
    from imitate.motion.kinematics import Kinematics

__all__ = ["TaskFrame", "TaskMap"]

_SINGULAR_RHO2 = SINGULAR_TOL**2


class TaskMap:
    r"""A task space on the robot (eq. 1 unless another is given): ``x (m,)``, ``J = dx/dq``.

    An object's angle and gaze-forward component depend on its long axis ``a`` only:
    ``d(angle, forward) = C R_gaze^T da`` with ``C = [[-p_d, p_r, 0] / rho^2, [0, 0, 1]]``
    (``p = R_gaze^T a``, ``rho^2 = p_r^2 + p_d^2``). ``A = da/dq`` ``(3, n)`` is the Jacobian of
    the point ``o + a`` minus that of the origin ``o``, so every row of ``J`` and of its
    derivative along ``b`` (:meth:`rates`: ``C' R_gaze^T A + C R_gaze^T A'``) comes from
    ``mj_jac`` and ``mj_jacDot`` of the four points ``o_tool, o_target, o_tool + a_tool,
    o_target + a_target`` (the compiled :meth:`evaluate` and :meth:`curvature` get ``A`` as
    ``omega x a`` from the rotational Jacobians of ``o_tool`` and ``o_target`` instead: two
    MuJoCo calls, not four). The objects' frames give ``o`` (origin) and ``a`` (``z`` axis). A
    position in a held object's own frame, ``E(a) p``, is not linear in the points: its rows add
    ``E_A p`` (the frame turning with the axis) to ``E P``. It runs in the planner's inner loop:
    :meth:`evaluate` and :meth:`curvature` are compiled (:mod:`imitate.motion._planner`) around
    MuJoCo's Jacobians.

    Args:
        kin: The kinematics (its held objects give the tool's and the target's poses).
        tool, target: Body names of the two objects.
        gaze: ``R_gaze`` ``(3, 3)``, right-handed, columns right, down, forward, fixed in the
            world (see :mod:`imitate.taskspace`).
        fixed_joints: Joints whose Jacobian columns are zeroed.
        space: The task space; its places are bodies of the model fixed to the world.

    Raises:
        ImitateError: On a bad gaze frame, an unknown joint, or a place that is no body fixed to
            the world.
    """

    def __init__(
        self,
        kin: Kinematics,
        tool: str,
        target: str,
        gaze: ArrayLike,
        fixed_joints: Sequence[str] = (),
        space: TaskSpace = EQ1,
    ):
        self.kin, self.space, self.m = kin, space, space.m
        self.tool, self.target = kin.model.body(tool).id, kin.model.body(target).id
        self.gaze = check_gaze(gaze)
        unknown = sorted(set(fixed_joints) - set(kin.joints))
        if unknown:
            raise ImitateError(f"fixed_joints {unknown} unknown; accepted: {list(kin.joints)}")
        self.driven = np.array([j not in fixed_joints for j in kin.joints])
        places = [_place(kin.model, name) for name in space.places]
        self._bodies = np.array([self.tool, self.target, *places])
        anchors = {**{role: k for k, role in enumerate(OBJECTS)},
                   **{name: 2 + k for k, name in enumerate(space.places)}}
        frames: dict[str | None, int] = {None: -1, **{r: k for k, r in enumerate(OBJECTS)}}
        self._terms = np.array([
            (_planner.RELATIVE, anchors[t.of], anchors[t.to], start, frames[t.frame])
            if isinstance(t, Relative) else (_planner.ANGLES, anchors[t.of], -1, start, -1)
            for t, start in zip(space.terms, space.starts, strict=True)
        ], dtype=np.intp)
        self._points_of = (self.tool, self.target, self.tool, self.target)
        self._gaze = np.ascontiguousarray(self.gaze)
        self._gaze_t = np.ascontiguousarray(self.gaze.T)
        self._mask = self.driven.astype(float)
        self._xpos, self._xmat = kin.data.xpos, kin.data.xmat  # views, kept once
        self._objects = self._points_of[:2]
        self._dof = np.ascontiguousarray(kin.dof_adr, dtype=np.intp)
        # Buffers of evaluate (the objects' Jacobians) and curvature (their rates), nv columns.
        nv = kin.model.nv
        self._jac = np.empty((2, 2, 3, nv))
        self._rates = np.empty((2, 2, 2, 3, nv))
        # Where no term is in an object's own frame, the frames and the translational Jacobians
        # are written at every posture but never read: one buffer for all, not one per step.
        framed = bool(np.any(self._terms[:, 4] >= 0))
        self._shared = None if framed else self._frame_buffers()

    def origins(self, places: Sequence[str]) -> dict[str, np.ndarray]:
        """Where each of ``places`` (bodies fixed to the world) stands: ``(3,)`` [m], world
        frame.

        Raises:
            ImitateError: a place that is no body fixed to the world.
        """
        model = self.kin.model
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        return {name: data.xpos[_place(model, name)].copy() for name in places}

    def __call__(self, angle_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(x (m,), J (m, n))`` at the kinematics' last update; angles on the branch nearest to
        ``angle_ref`` ``(2,)`` [rad] (the tool's, the target's; :meth:`TaskSpace.angle_ref`),
        and equal to it where undefined."""
        x, J, _ = self.evaluate(angle_ref)
        return x, J

    def evaluate(self, angle_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray, TaskFrame]:
        """As :meth:`__call__`, and the :class:`TaskFrame` that :meth:`rates` needs."""
        points, proj, inv, x, rows, axes = (
            np.empty((4, 3)), np.empty((2, 3)), np.empty(2), np.empty(self.m), np.empty((2, 3)),
            np.empty((2, 3)),
        )
        framed, trans_jac = self._shared or self._frame_buffers()
        _planner._task_state(
            self._xpos, self._xmat, self._bodies, self._terms, self._gaze,
            np.ascontiguousarray(angle_ref, dtype=float), _SINGULAR_RHO2,
            points, proj, inv, x, rows, axes, framed,
        )
        jac = self.kin.frame_jacobians(self._objects, points, self._jac)
        n = self.kin.n
        J, axis_jac, rot_jac = np.empty((self.m, n)), np.empty((2, 3, n)), np.empty((2, 3, n))
        _planner._task_jacobian(
            jac, self._dof, self._terms, axes, rows, self._gaze, framed, self._mask, J, axis_jac,
            rot_jac, trans_jac,
        )
        return x, J, TaskFrame(points, proj, inv, rows, axis_jac, axes, rot_jac, trans_jac,
                               framed)

    def _frame_buffers(self) -> tuple[np.ndarray, np.ndarray]:
        """Fresh ``framed (n_terms, 5, 3)`` and ``trans_jac (2, 3, n)`` (see :class:`TaskFrame`)."""
        return (np.zeros((len(self._terms), _planner.FRAME_ROWS, 3)),
                np.empty((2, 3, self.kin.n)))

    def _mix(self, frame: TaskFrame) -> np.ndarray:
        """``(m, 12)``: ``J`` as a linear map of the stacked point Jacobians ``(4 * 3, n)``
        (a place's Jacobian is 0)."""
        mix = np.zeros((self.m, 12))
        forward = self.gaze[:, 2]
        for kind, first, second, row, own in self._terms:
            if kind == _planner.RELATIVE and own >= 0:
                continue  # not linear in the points: :meth:`_framed_rates`
            if kind == _planner.RELATIVE:
                for anchor, sign in ((first, 1.0), (second, -1.0)):
                    if anchor < 2:
                        mix[row : row + 3, 3 * anchor : 3 * anchor + 3] = sign * np.eye(3)
                continue
            for r, weights in ((row, frame.rows[first]), (row + 1, forward)):
                mix[r, 6 + 3 * first : 9 + 3 * first] = weights
                mix[r, 3 * first : 3 + 3 * first] = -weights
        return mix

    def rates(self, qdot: np.ndarray, frame: TaskFrame) -> np.ndarray:
        """``D_b J`` ``(k, m, n)``: derivatives of ``J`` along each joint direction ``b`` in
        ``qdot`` ``(k, n)`` [rad], at the posture of ``frame`` (from :meth:`evaluate`), which the
        kinematics must be updated to (held objects may be left out)."""
        n = self.kin.n
        rate = np.empty((len(qdot), 12, n))
        for k, b in enumerate(qdot):
            rate[k] = self.kin.point_jacobian_rates(self._points_of, frame.points, b).reshape(12, n)
        # C' (only its angle row moves): d(-p_d s, p_r s) with s = 1 / rho^2, p' = R^T A b.
        dproj = self._gaze_t @ (frame.axis_jac @ qdot.T)  # (2, 3, k)
        (pr, pd), s = frame.proj[:, :2, None].transpose(1, 0, 2), frame.inv[:, None]
        ds = -2.0 * (pr * dproj[:, 0] + pd * dproj[:, 1]) * s * s  # (2, k)
        r, d, _ = self.gaze.T
        coef_r, coef_d = -dproj[:, 1] * s - pd * ds, dproj[:, 0] * s + pr * ds  # (2, k)
        row_dot = coef_r[..., None] * r + coef_d[..., None] * d  # (2, k, 3)
        out = self._mix(frame) @ rate
        for i, (kind, first, _, row, _) in enumerate(self._terms):
            if kind == _planner.ANGLES:
                out[:, row] += row_dot[first] @ frame.axis_jac[first]
            else:
                self._framed_rates(i, qdot, rate, frame, out)
        out *= self._mask
        return out

    def _framed_rates(
        self, i: int, qdot: np.ndarray, rate: np.ndarray, frame: TaskFrame, out: np.ndarray
    ) -> None:
        """Adds to ``out (k, m, n)`` the rates of term ``i``, if a position in an object's
        frame: ``D_b (E p)_j = E_{A_j a'} p + E_{D_b A_j} p + E_{A_j} p' + E_{a'} P_j +
        E D_b P_j`` (``rate (k, 12, n)`` the points' Jacobian rates, see :meth:`rates`)."""
        _, first, second, row, own = self._terms[i]
        if own < 0:
            return
        entry, axis, axis_jac = frame.framed[i], frame.axes[own], frame.axis_jac[own]
        e, p, g = entry[:3], entry[3], entry[4]
        move = sum((sign * frame.trans_jac[anchor] for anchor, sign in ((first, 1), (second, -1))
                    if anchor < 2), np.zeros(axis_jac.shape))  # P (3, n)
        change, turned, moved = (np.empty((2, 3, 3)) for _ in range(3))
        for k, b in enumerate(qdot):
            rows = rate[k].reshape(4, 3, -1)
            shift = sum((sign * rows[anchor] for anchor, sign in ((first, 1), (second, -1))
                         if anchor < 2), np.zeros(axis_jac.shape))  # D_b P
            axis_rate = rows[2 + own] - rows[own]  # D_b A
            a_dot, p_dot = axis_jac @ b, move @ b
            _planner._frame_change(axis, g, a_dot, a_dot, moved)
            for j in range(len(b)):
                _planner._frame_change(axis, g, axis_jac[:, j].copy(), a_dot, change)
                _planner._frame_change(axis, g, axis_rate[:, j].copy(), a_dot, turned)
                out[k, row : row + 3, j] += (change[1] @ p + turned[0] @ p + change[0] @ p_dot
                                             + moved[0] @ move[:, j] + e @ shift[:, j])

    def curvature(
        self, a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, frame: TaskFrame
    ) -> np.ndarray:
        """``a^T D_b J + c^T D_d J`` ``(n,)`` for task vectors ``a, c`` ``(m,)`` and joint
        directions ``b, d`` ``(n,)`` [rad]: two contractions of :meth:`rates` without forming
        ``D J`` (``mj_jacDot`` of the objects' origins along ``b`` and ``d``, translational
        and rotational, then one compiled pass). Same preconditions as :meth:`rates`."""
        kin, rates = self.kin, self._rates
        kin.frame_jacobian_rates(self._objects, frame.points, (b, d), rates)
        out = np.empty(kin.n)
        _planner._curvature(
            a, b, c, d, rates, self._dof, self._terms, frame.axes, frame.rows, frame.proj,
            frame.inv, frame.axis_jac, frame.rot_jac, frame.trans_jac, frame.framed, self._gaze,
            self._mask, out,
        )
        return out


def _place(model, name: str) -> int:
    """The body id of place ``name``.

    Raises:
        ImitateError: No such body, or one that is not fixed to the world.
    """
    try:
        body = model.body(name)
    except KeyError:
        raise ImitateError(f"place {name!r} is no body of the scene") from None
    if model.body_weldid[body.id] != 0:
        raise ImitateError(f"place {name!r} must be fixed to the world; it moves with a joint")
    return body.id


class TaskFrame(NamedTuple):
    """What :meth:`TaskMap.rates` reuses from :meth:`TaskMap.evaluate` at one posture.

    Attributes:
        points: ``(4, 3)`` tool and target origins, then those plus their long axes ``a`` [m].
        proj: ``(2, 3)`` the axes' gaze coordinates ``p`` (right, down, forward).
        inv: ``(2,)`` ``1 / rho^2`` per object (0 where the axis is along the gaze: the angle is
            undefined there and its gradient is taken as 0).
        rows: ``(2, 3)`` per object the gradient of its angle with respect to its axis,
            ``(-p_d r + p_r d) / rho^2`` (``r``, ``d``: gaze right and down).
        axis_jac: ``da/dq`` ``(2, 3, n)``, fixed joints' columns included.
        axes: ``(2, 3)`` the long axes ``a``.
        rot_jac: ``(2, 3, n)`` the objects' rotational Jacobians (``da/dq_j = omega_j x a``).
        trans_jac: ``(2, 3, n)`` the objects' translational Jacobians.
        framed: ``(n_terms, 5, 3)`` per position in an object's frame, the frame's axes, the
            position in the world and the gaze column that fixes the frame
            (:func:`imitate.motion._planner._task_state`). In a space without such a position
            these two are one buffer shared by every posture, read by nothing.
    """

    points: np.ndarray
    proj: np.ndarray
    inv: np.ndarray
    rows: np.ndarray
    axis_jac: np.ndarray
    axes: np.ndarray
    rot_jac: np.ndarray
    trans_jac: np.ndarray
    framed: np.ndarray
