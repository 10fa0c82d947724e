r"""The pouring task space (paper eq. 1): the map of demonstrations and the map of the robot.

``x = (x_diff, phi_b, phi_g)`` has 7 dimensions:

=====  ==================  =====  ==================================================================
index  name                unit   meaning
=====  ==================  =====  ==================================================================
0-2    ``dx, dy, dz``      m      ``p_bottle - p_glass`` in the world frame
3      ``bottle_angle``    rad    angle of the bottle's long axis projected onto the image plane,
                                  ``atan2(a . d, a . r)`` (clockwise in the image, see below)
4      ``bottle_gaze``     1      component of the bottle's long axis along the gaze, ``a . f``
5      ``glass_angle``     rad    as 3, for the glass
6      ``glass_gaze``      1      as 4, for the glass
=====  ==================  =====  ==================================================================

Two maps compute it: :func:`task_space` maps observed object trajectories (positions and long
axes) to demonstrations, and :class:`TaskMap` maps the robot's joint angles ``q`` through the
objects it holds, with ``J = dx/dq`` and its derivatives for the planner. They agree: at any
posture :class:`TaskMap`'s value is :func:`task_space` of the held objects' frames.

The gaze frame, one convention everywhere: ``R_gaze`` is a right-handed orthonormal matrix
(determinant +1) whose columns are camera right ``r``, image down ``d`` and gaze forward ``f``
in world coordinates, i.e. OpenCV's camera axes (``perception.gaze_frame`` of a camera,
:func:`gaze_frame` from a gaze direction; a MuJoCo camera, whose axes are right, up, backward,
gives the columns ``x, -y, -z`` of its rotation). For a unit long axis ``a`` the angle is
``atan2(a . d, a . r)``: measured from "right" towards "down", i.e. clockwise in the camera
image (a positive rotation about ``f`` by the right-hand rule). An upright object seen by a
level camera has angle ``-pi/2``; tilting its top towards the image's right brings the angle
towards 0. Over a demonstration the angles are unwrapped so they are continuous; on the robot
side an ``angle_ref`` picks the ``2 pi`` branch nearest to it.

Singularity: when the axis is (nearly) parallel to the gaze its projection
``rho = hypot(a . r, a . d)`` vanishes and the angle is undefined. Below ``SINGULAR_TOL`` the
demonstration map holds the last defined angle (the first defined one before it, 0 if none is
defined), and the robot map returns ``angle_ref`` with a zero Jacobian row, so an optimizer
neither chases nor is thrown by an undefined quantity; the ``a . f`` component stays defined
and keeps its exact Jacobian.

Robot-side Jacobians use MuJoCo's conventions: ``jac_pos = dp/dq`` and the rotational Jacobian
maps joint velocities to the world-frame angular velocity ``omega``, so ``da/dq[:, i] =
jac_rot[:, i] x a``; :class:`TaskMap` gets ``da/dq`` as the Jacobian of the point ``o + a``
minus that of the object's origin ``o``.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, NamedTuple

import numpy as np
from numpy.typing import ArrayLike

from imitate.errors import ImitateError
from imitate.motion import _planner

if TYPE_CHECKING:
    from imitate.motion.kinematics import Kinematics

__all__ = [
    "SINGULAR_TOL",
    "TASK_DIMS",
    "TASK_UNITS",
    "TaskFrame",
    "TaskMap",
    "gaze_frame",
    "object_orientation",
    "task_space",
]

TASK_DIMS = ("dx", "dy", "dz", "bottle_angle", "bottle_gaze", "glass_angle", "glass_gaze")
TASK_UNITS = ("m", "m", "m", "rad", "1", "rad", "1")
# Projected length ``rho`` of a unit axis onto the image plane below which its angle is
# undefined (the axis lies within about 1e-6 rad of the gaze).
SINGULAR_TOL = 1e-6
_SINGULAR_RHO2 = SINGULAR_TOL**2
_ANGLE_COLUMNS = (3, 5)


def _check_gaze(gaze: ArrayLike) -> np.ndarray:
    """Validates ``R_gaze`` as a right-handed orthonormal 3x3 matrix."""
    R = np.asarray(gaze, dtype=float)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise ImitateError(f"gaze must be a finite orthonormal 3x3 matrix; got shape {R.shape}")
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6) or not np.linalg.det(R) > 0:
        raise ImitateError(
            "gaze must be right-handed orthonormal (determinant +1) with columns (right, down, "
            f"forward), OpenCV's camera axes; got R^T R =\n{R.T @ R}\nand determinant "
            f"{np.linalg.det(R):+.6f}"
        )
    return R


def gaze_frame(forward: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> np.ndarray:
    """Gaze frame looking along ``forward``, the image's up as close as possible to ``up``.

    Args:
        forward: Gaze direction in the world frame, shape ``(3,)``, non-zero.
        up: World direction the image's up should lean towards, shape ``(3,)``, not parallel to
            ``forward``.

    Returns:
        ``R_gaze``, shape ``(3, 3)``, columns (right, down, forward), right-handed:
        ``right = forward x up`` normalised, ``down = forward x right``.

    Raises:
        ImitateError: If ``forward`` is zero or parallel to ``up``.
    """
    f = np.asarray(forward, dtype=float)
    norm = np.linalg.norm(f)
    if f.shape != (3,) or not norm > 0:
        raise ImitateError(f"forward must be a non-zero 3-vector; got {forward!s}")
    f = f / norm
    r = np.cross(f, np.asarray(up, dtype=float))
    if not np.linalg.norm(r) > 1e-9:
        raise ImitateError(f"up {up!s} must not be parallel to forward {forward!s}")
    r /= np.linalg.norm(r)
    return np.column_stack((r, np.cross(f, r), f))


def object_orientation(
    axis: ArrayLike, gaze: ArrayLike, *, singular_tol: float = SINGULAR_TOL
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orientation ``phi`` of one object from its long axis, without unwrapping.

    Args:
        axis: Long axes in the world frame, shape ``(..., 3)``; normalised here, non-zero.
        gaze: ``R_gaze``, shape ``(3, 3)``.
        singular_tol: Projected length below which the angle is undefined.

    Returns:
        ``(angle, gaze_component, defined)``, each of shape ``(...)``: the angle in
        ``[-pi, pi]`` [rad], ``a . f`` [1] and whether the angle is defined.

    Raises:
        ImitateError: On a zero or non-finite axis or a bad gaze frame.
    """
    R = _check_gaze(gaze)
    a = np.asarray(axis, dtype=float)
    norm = np.linalg.norm(a, axis=-1)
    if a.shape[-1:] != (3,) or not np.all(np.isfinite(a)) or np.any(norm == 0.0):
        raise ImitateError(
            f"axis must be finite non-zero vectors of shape (..., 3); got shape {a.shape}"
        )
    c = (a / norm[..., None]) @ R
    pr, pd, pf = c[..., 0], c[..., 1], c[..., 2]
    return np.arctan2(pd, pr), pf, np.hypot(pr, pd) >= singular_tol


def _hold_undefined(angle: np.ndarray, defined: np.ndarray) -> np.ndarray:
    """Replaces undefined angles by the last defined one (the first defined one before it)."""
    if defined.all():
        return angle
    if not defined.any():
        return np.zeros_like(angle)
    idx = np.where(defined, np.arange(angle.size), 0)
    np.maximum.accumulate(idx, out=idx)
    first = int(np.argmax(defined))
    idx[:first] = first
    return angle[idx]


def task_space(
    p_bottle: ArrayLike,
    a_bottle: ArrayLike,
    p_glass: ArrayLike,
    a_glass: ArrayLike,
    gaze: ArrayLike,
    *,
    singular_tol: float = SINGULAR_TOL,
) -> np.ndarray:
    """Maps object trajectories to the task space of eq. 1, angles unwrapped over time.

    Args:
        p_bottle: Bottle positions, shape ``(n_steps, 3)`` [m], world frame.
        a_bottle: Bottle long axes, shape ``(n_steps, 3)``, world frame, any non-zero length.
        p_glass: Glass positions, shape ``(n_steps, 3)`` [m].
        a_glass: Glass long axes, shape ``(n_steps, 3)``.
        gaze: ``R_gaze``, shape ``(3, 3)``, right-handed, columns (right, down, forward).
        singular_tol: Projected axis length below which an angle is undefined and held.

    Returns:
        ``x``, shape ``(n_steps, 7)``, see the module table for units.

    Raises:
        ImitateError: On mismatched shapes, non-finite values, zero axes or a bad gaze frame.
    """
    arrays = [np.asarray(v, dtype=float) for v in (p_bottle, a_bottle, p_glass, a_glass)]
    shape = arrays[0].shape
    if len(shape) != 2 or shape[1] != 3 or shape[0] == 0:
        raise ImitateError(f"p_bottle must have shape (n_steps, 3); got {shape}")
    for name, arr in zip(("a_bottle", "p_glass", "a_glass"), arrays[1:], strict=True):
        if arr.shape != shape:
            raise ImitateError(f"{name} must have shape {shape} like p_bottle; got {arr.shape}")
    if not all(np.all(np.isfinite(arr)) for arr in arrays):
        raise ImitateError("object trajectories must be finite (no NaN or inf)")
    x = np.empty((shape[0], 7))
    x[:, :3] = arrays[0] - arrays[2]
    for col, axis in zip(_ANGLE_COLUMNS, (arrays[1], arrays[3]), strict=True):
        angle, along, defined = object_orientation(axis, gaze, singular_tol=singular_tol)
        x[:, col] = np.unwrap(_hold_undefined(angle, defined))
        x[:, col + 1] = along
    return x


class TaskMap:
    r"""Eq. 1 on the robot: ``x = (p_b - p_g, phi_b, phi_g)`` and ``J = dx/dq`` ``(7, n)``.

    An object's angle and gaze-forward component depend on its long axis ``a`` only:
    ``d(angle, forward) = C R_gaze^T da`` with ``C = [[-p_d, p_r, 0] / rho^2, [0, 0, 1]]``
    (``p = R_gaze^T a``, ``rho^2 = p_r^2 + p_d^2``). ``A = da/dq`` ``(3, n)`` is the Jacobian of
    the point ``o + a`` minus that of the origin ``o``, so every row of ``J`` and of its
    derivative along ``b`` (:meth:`rates`: ``C' R_gaze^T A + C R_gaze^T A'``) comes from
    ``mj_jac`` and ``mj_jacDot`` of the four points ``o_b, o_g, o_b + a_b, o_g + a_g`` (the
    compiled :meth:`evaluate` and :meth:`curvature` get ``A`` as ``omega x a`` from the
    rotational Jacobians of ``o_b`` and ``o_g`` instead: two MuJoCo calls, not four). The
    objects' frames give ``o`` (origin) and ``a`` (``z`` axis), as for :func:`task_space`. It
    runs in the planner's inner loop: :meth:`evaluate` and :meth:`curvature` are compiled
    (:mod:`imitate.motion._planner`) around MuJoCo's Jacobians.

    Args:
        kin: The kinematics (its held objects give the bottle and glass poses).
        bottle, glass: Body names of the two objects.
        gaze: ``R_gaze`` ``(3, 3)``, right-handed, columns right, down, forward, fixed in the
            world (see the module docstring).
        fixed_joints: Joints whose Jacobian columns are zeroed.

    Raises:
        ImitateError: On a bad gaze frame or an unknown joint.
    """

    m = 7

    def __init__(
        self,
        kin: Kinematics,
        bottle: str,
        glass: str,
        gaze: ArrayLike,
        fixed_joints: Sequence[str] = (),
    ):
        self.kin = kin
        self.bottle, self.glass = kin.model.body(bottle).id, kin.model.body(glass).id
        self.gaze = _check_gaze(gaze)
        unknown = sorted(set(fixed_joints) - set(kin.joints))
        if unknown:
            raise ImitateError(f"fixed_joints {unknown} unknown; accepted: {list(kin.joints)}")
        self.driven = np.array([j not in fixed_joints for j in kin.joints])
        self._bodies = np.array([self.bottle, self.glass])
        self._points_of = (self.bottle, self.glass, self.bottle, self.glass)
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

    def __call__(self, angle_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(x (7,), J (7, n))`` at the kinematics' last update; angles on the branch nearest to
        ``angle_ref`` ``(2,)`` [rad] (and equal to it where undefined)."""
        x, J, _ = self.evaluate(angle_ref)
        return x, J

    def evaluate(self, angle_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray, TaskFrame]:
        """As :meth:`__call__`, and the :class:`TaskFrame` that :meth:`rates` needs."""
        points, proj, inv, x, rows, axes = (
            np.empty((4, 3)), np.empty((2, 3)), np.empty(2), np.empty(self.m), np.empty((2, 3)),
            np.empty((2, 3)),
        )
        _planner._task_state(
            self._xpos, self._xmat, self._bodies, self._gaze,
            np.ascontiguousarray(angle_ref, dtype=float), _SINGULAR_RHO2,
            points, proj, inv, x, rows, axes,
        )
        jac = self.kin.frame_jacobians(self._objects, points, self._jac)
        n = self.kin.n
        J, axis_jac, rot_jac = np.empty((self.m, n)), np.empty((2, 3, n)), np.empty((2, 3, n))
        _planner._task_jacobian(
            jac, self._dof, axes, rows, self._gaze, self._mask, J, axis_jac, rot_jac
        )
        return x, J, TaskFrame(points, proj, inv, rows, axis_jac, axes, rot_jac)

    def _mix(self, frame: TaskFrame) -> np.ndarray:
        """``(7, 12)``: ``J`` as a linear map of the stacked point Jacobians ``(4 * 3, n)``."""
        mix = np.zeros((7, 12))
        mix[:3, :3], mix[:3, 3:6] = np.eye(3), -np.eye(3)
        forward = self.gaze[:, 2]
        for o in range(2):
            for row, weights in ((3 + 2 * o, frame.rows[o]), (4 + 2 * o, forward)):
                mix[row, 6 + 3 * o : 9 + 3 * o] = weights
                mix[row, 3 * o : 3 + 3 * o] = -weights
        return mix

    def rates(self, qdot: np.ndarray, frame: TaskFrame) -> np.ndarray:
        """``D_b J`` ``(k, 7, n)``: derivatives of ``J`` along each joint direction ``b`` in
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
        out[:, 3::2] += (row_dot @ frame.axis_jac).transpose(1, 0, 2)
        out *= self._mask
        return out

    def curvature(
        self, a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, frame: TaskFrame
    ) -> np.ndarray:
        """``a^T D_b J + c^T D_d J`` ``(n,)`` for task vectors ``a, c`` ``(7,)`` and joint
        directions ``b, d`` ``(n,)`` [rad]: two contractions of :meth:`rates` without forming
        ``D J`` (``mj_jacDot`` of the objects' origins along ``b`` and ``d``, translational
        and rotational, then one compiled pass). Same preconditions as :meth:`rates`."""
        kin, rates = self.kin, self._rates
        kin.frame_jacobian_rates(self._objects, frame.points, (b, d), rates)
        out = np.empty(kin.n)
        _planner._curvature(
            a, b, c, d, rates, self._dof, frame.axes, frame.rows, frame.proj, frame.inv,
            frame.axis_jac, frame.rot_jac, self._gaze, self._mask, out,
        )
        return out


class TaskFrame(NamedTuple):
    """What :meth:`TaskMap.rates` reuses from :meth:`TaskMap.evaluate` at one posture.

    Attributes:
        points: ``(4, 3)`` bottle and glass origins, then those plus their long axes ``a`` [m].
        proj: ``(2, 3)`` the axes' gaze coordinates ``p`` (right, down, forward).
        inv: ``(2,)`` ``1 / rho^2`` per object (0 where the axis is along the gaze: the angle is
            undefined there and its gradient is taken as 0).
        rows: ``(2, 3)`` per object the gradient of its angle with respect to its axis,
            ``(-p_d r + p_r d) / rho^2`` (``r``, ``d``: gaze right and down).
        axis_jac: ``da/dq`` ``(2, 3, n)``, fixed joints' columns included.
        axes: ``(2, 3)`` the long axes ``a``.
        rot_jac: ``(2, 3, n)`` the objects' rotational Jacobians (``da/dq_j = omega_j x a``).
    """

    points: np.ndarray
    proj: np.ndarray
    inv: np.ndarray
    rows: np.ndarray
    axis_jac: np.ndarray
    axes: np.ndarray
    rot_jac: np.ndarray
