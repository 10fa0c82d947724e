r"""The task space (paper eq. 1): its columns, the gaze frame, and the map of object trajectories.

A bimanual task moves a **tool** (held by the right hand) to a **target** (held by the left).
``x = (x_diff, phi_tool, phi_target)`` has 7 dimensions:

=====  ==================  =====  ==================================================================
index  name                unit   meaning
=====  ==================  =====  ==================================================================
0-2    ``dx, dy, dz``      m      ``p_tool - p_target`` in the world frame (:data:`POSITION`)
3      ``tool_angle``      rad    angle of the tool's long axis projected onto the image plane,
                                  ``atan2(a . d, a . r)`` (clockwise in the image, see below)
4      ``tool_gaze``       1      component of the tool's long axis along the gaze, ``a . f``
5      ``target_angle``    rad    as 3, for the target
6      ``target_gaze``     1      as 4, for the target
=====  ==================  =====  ==================================================================

The angle columns 3 and 5 are :data:`ANGLES`. :func:`task_space` maps observed object
trajectories (positions and long axes) to demonstrations; the robot's map of its joint angles
(:class:`imitate.motion.taskspace.TaskMap`) agrees with it at every posture.

The gaze frame, one convention everywhere: ``R_gaze`` is a right-handed orthonormal matrix
(determinant +1) whose columns are camera right ``r``, image down ``d`` and gaze forward ``f``
in world coordinates, i.e. OpenCV's camera axes (:func:`gaze_of_camera` of a camera,
:func:`gaze_frame` from a gaze direction). For a unit long axis ``a`` the angle is
``atan2(a . d, a . r)``: measured from "right" towards "down", i.e. clockwise in the camera
image (a positive rotation about ``f`` by the right-hand rule). An upright object seen by a
level camera has angle ``-pi/2``; tilting its top towards the image's right brings the angle
towards 0. Over a demonstration the angles are unwrapped so they are continuous; on the robot
side an ``angle_ref`` picks the ``2 pi`` branch nearest to it.

Singularity: when the axis is (nearly) parallel to the gaze its projection
``rho = hypot(a . r, a . d)`` vanishes and the angle is undefined. Below :data:`SINGULAR_TOL`
the demonstration map holds the last defined angle (the first defined one before it, 0 if none
is defined), and the robot map returns ``angle_ref`` with a zero Jacobian row, so an optimizer
neither chases nor is thrown by an undefined quantity; the ``a . f`` component stays defined.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from imitate.errors import ImitateError

__all__ = [
    "ANGLES",
    "POSITION",
    "SINGULAR_TOL",
    "TASK_DIMS",
    "TASK_UNITS",
    "check_gaze",
    "gaze_frame",
    "gaze_of_camera",
    "image_angle",
    "object_orientation",
    "task_space",
]

TASK_DIMS = ("dx", "dy", "dz", "tool_angle", "tool_gaze", "target_angle", "target_gaze")
TASK_UNITS = ("m", "m", "m", "rad", "1", "rad", "1")
POSITION = slice(0, 3)  # the columns of p_tool - p_target [m]
ANGLES = np.array((3, 5))  # the columns of the tool's and the target's angles [rad]
ANGLES.flags.writeable = False
# Projected length ``rho`` of a unit axis onto the image plane below which its angle is
# undefined (the axis lies within about 1e-6 rad of the gaze).
SINGULAR_TOL = 1e-6


def check_gaze(gaze: ArrayLike) -> np.ndarray:
    """``gaze`` as ``R_gaze`` ``(3, 3)`` float.

    Raises:
        ImitateError: If it is not a finite right-handed orthonormal 3x3 matrix.
    """
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


def gaze_of_camera(rotation: ArrayLike, *, mujoco: bool = False) -> np.ndarray:
    """The gaze frame of a camera: its axes right, image down and forward in world coordinates.

    Args:
        rotation: ``(3, 3)``: OpenCV's world-to-camera rotation, whose rows are the camera's
            right, down and forward axes in world coordinates (a pinhole camera's); with
            ``mujoco``, MuJoCo's camera orientation (``cam_xmat``), whose columns are its right,
            up and backward axes.
        mujoco: Whether ``rotation`` is MuJoCo's camera orientation.

    Returns:
        ``R_gaze`` ``(3, 3)``, columns (right, down, forward), a new array.

    Raises:
        ImitateError: If the result is not right-handed orthonormal.
    """
    R = np.asarray(rotation, dtype=float)
    return check_gaze(R * np.array([1.0, -1.0, -1.0]) if mujoco else R.T.copy())


def _angle(projected: np.ndarray) -> np.ndarray:
    """``atan2(a . d, a . r)`` [rad] of axes' gaze coordinates ``(..., 3)`` (right, down, ...)."""
    return np.arctan2(projected[..., 1], projected[..., 0])


def image_angle(axis: ArrayLike, gaze: ArrayLike) -> np.ndarray:
    """The angle of :func:`object_orientation` alone, for observed axes that may be missing.

    Args:
        axis: Long axes in the world frame, shape ``(..., 3)``, any length; NaN where the
            object was not seen.
        gaze: ``R_gaze``, shape ``(3, 3)``.

    Returns:
        The angles in ``[-pi, pi]`` [rad], shape ``(...)``; NaN where ``axis`` is, not
        unwrapped.

    Raises:
        ImitateError: On a bad gaze frame.
    """
    return _angle(np.asarray(axis, dtype=float) @ check_gaze(gaze))


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
    R = check_gaze(gaze)
    a = np.asarray(axis, dtype=float)
    norm = np.linalg.norm(a, axis=-1)
    if a.shape[-1:] != (3,) or not np.all(np.isfinite(a)) or np.any(norm == 0.0):
        raise ImitateError(
            f"axis must be finite non-zero vectors of shape (..., 3); got shape {a.shape}"
        )
    c = (a / norm[..., None]) @ R
    return _angle(c), c[..., 2], np.hypot(c[..., 0], c[..., 1]) >= singular_tol


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
    p_tool: ArrayLike,
    a_tool: ArrayLike,
    p_target: ArrayLike,
    a_target: ArrayLike,
    gaze: ArrayLike,
    *,
    singular_tol: float = SINGULAR_TOL,
) -> np.ndarray:
    """Maps object trajectories to the task space of eq. 1, angles unwrapped over time.

    Args:
        p_tool: Tool positions, shape ``(n_steps, 3)`` [m], world frame.
        a_tool: Tool long axes, shape ``(n_steps, 3)``, world frame, any non-zero length.
        p_target: Target positions, shape ``(n_steps, 3)`` [m].
        a_target: Target long axes, shape ``(n_steps, 3)``.
        gaze: ``R_gaze``, shape ``(3, 3)``, right-handed, columns (right, down, forward).
        singular_tol: Projected axis length below which an angle is undefined and held.

    Returns:
        ``x``, shape ``(n_steps, 7)``, see the module table for units.

    Raises:
        ImitateError: On mismatched shapes, non-finite values, zero axes or a bad gaze frame.
    """
    arrays = [np.asarray(v, dtype=float) for v in (p_tool, a_tool, p_target, a_target)]
    shape = arrays[0].shape
    if len(shape) != 2 or shape[1] != 3 or shape[0] == 0:
        raise ImitateError(f"p_tool must have shape (n_steps, 3); got {shape}")
    for name, arr in zip(("a_tool", "p_target", "a_target"), arrays[1:], strict=True):
        if arr.shape != shape:
            raise ImitateError(f"{name} must have shape {shape} like p_tool; got {arr.shape}")
    if not all(np.all(np.isfinite(arr)) for arr in arrays):
        raise ImitateError("object trajectories must be finite (no NaN or inf)")
    x = np.empty((shape[0], 7))
    x[:, POSITION] = arrays[0] - arrays[2]
    for col, axis in zip(ANGLES, (arrays[1], arrays[3]), strict=True):
        angle, along, defined = object_orientation(axis, gaze, singular_tol=singular_tol)
        x[:, col] = np.unwrap(_hold_undefined(angle, defined))
        x[:, col + 1] = along
    return x
