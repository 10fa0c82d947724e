r"""The pouring task space (paper eq. 1) for demonstrations and for the robot.

``x = (x_diff, phi_b, phi_g)`` has 7 dimensions:

=====  ==================  =====  ==================================================================
index  name                unit   meaning
=====  ==================  =====  ==================================================================
0-2    ``dx, dy, dz``      m      ``p_bottle - p_glass`` in the world frame
3      ``bottle_angle``    rad    angle of the bottle's long axis projected onto the image plane,
                                  measured around the gaze vector (from camera right towards up)
4      ``bottle_gaze``     1      component of the bottle's long axis along the gaze, ``a . f``
5      ``glass_angle``     rad    as 3, for the glass
6      ``glass_gaze``      1      as 4, for the glass
=====  ==================  =====  ==================================================================

The gaze frame ``R_gaze`` is an orthonormal matrix whose columns are camera right ``r``, camera
up ``u`` and gaze forward ``f`` in world coordinates (:func:`gaze_frame` builds one). For a
physical camera this frame is left-handed (``r x u = -f``, determinant -1); a right-handed one
(e.g. OpenCV's right, down, forward) is accepted as well. For a unit long axis ``a`` the angle is
``atan2(a . u, a . r)``: counter-clockwise in the camera image from "right" towards "up", i.e.
measured around the gaze vector. Over a demonstration the angles are unwrapped so they are
continuous; on the robot side an ``angle_ref`` picks the ``2 pi`` branch nearest to it.

Singularity: when the axis is (nearly) parallel to the gaze its projection
``rho = hypot(a . r, a . u)`` vanishes and the angle is undefined. Below ``singular_tol`` the
demonstration map holds the last defined angle (the first defined one before it, 0 if none is
defined), and the robot map returns ``angle_ref`` (when given) with a zero Jacobian row, so an
optimiser neither chases nor is thrown by an undefined quantity; the ``a . f`` component stays
defined and keeps its exact Jacobian.

Robot-side Jacobians use MuJoCo's conventions: ``jac_pos = dp/dq`` and ``jac_rot`` maps joint
velocities to the world-frame angular velocity ``omega``, so ``da/dq[:, i] = jac_rot[:, i] x a``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from imitate.errors import ImitateError

__all__ = [
    "TASK_DIMS",
    "TASK_UNITS",
    "ObjectKinematics",
    "gaze_frame",
    "object_orientation",
    "task_space",
    "task_state",
]

TASK_DIMS = ("dx", "dy", "dz", "bottle_angle", "bottle_gaze", "glass_angle", "glass_gaze")
TASK_UNITS = ("m", "m", "m", "rad", "1", "rad", "1")
_ANGLE_COLUMNS = (3, 5)


def _check_gaze(gaze: ArrayLike) -> np.ndarray:
    """Validates ``R_gaze`` as an orthonormal 3x3 matrix (either handedness)."""
    R = np.asarray(gaze, dtype=float)
    if R.shape != (3, 3) or not np.all(np.isfinite(R)):
        raise ImitateError(f"gaze must be a finite orthonormal 3x3 matrix; got shape {R.shape}")
    if not np.allclose(R.T @ R, np.eye(3), atol=1e-6):
        raise ImitateError(
            "gaze must be orthonormal with columns (right, up, forward); got R^T R =\n"
            f"{R.T @ R}"
        )
    return R


def gaze_frame(forward: ArrayLike, up: ArrayLike = (0.0, 0.0, 1.0)) -> np.ndarray:
    """Gaze frame looking along ``forward`` with the camera's up as close as possible to ``up``.

    Args:
        forward: Gaze direction in the world frame, shape ``(3,)``, non-zero.
        up: World direction the camera's up should lean towards, shape ``(3,)``, not parallel to
            ``forward``.

    Returns:
        ``R_gaze``, shape ``(3, 3)``, columns (right, up, forward), left-handed like a camera:
        ``right = forward x up`` normalised, camera ``up = right x forward``.

    Raises:
        ImitateError: If ``forward`` is zero or parallel to ``up``.
    """
    f = np.asarray(forward, dtype=float)
    norm = np.linalg.norm(f)
    if f.shape != (3,) or not norm > 0:
        raise ImitateError(f"forward must be a non-zero 3-vector; got {forward}")
    f = f / norm
    r = np.cross(f, np.asarray(up, dtype=float))
    if not np.linalg.norm(r) > 1e-9:
        raise ImitateError(f"up {up} must not be parallel to forward {forward}")
    r /= np.linalg.norm(r)
    return np.column_stack((r, np.cross(r, f), f))


def _projections(axis: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, ...]:
    """Components ``(a . r, a . u, a . f)`` of axes of shape ``(..., 3)``."""
    c = axis @ R
    return c[..., 0], c[..., 1], c[..., 2]


def object_orientation(
    axis: ArrayLike, gaze: ArrayLike, *, singular_tol: float = 1e-6
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orientation ``phi`` of one object from its long axis, without unwrapping.

    Args:
        axis: Long axes in the world frame, shape ``(..., 3)``; normalised here, non-zero.
        gaze: ``R_gaze``, shape ``(3, 3)``.
        singular_tol: Projected length below which the angle is undefined.

    Returns:
        ``(angle, gaze_component, defined)``, each of shape ``(...)``: the angle in
        ``(-pi, pi]`` [rad], ``a . f`` [1] and whether the angle is defined.

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
    pr, pu, pf = _projections(a / norm[..., None], R)
    return np.arctan2(pu, pr), pf, np.hypot(pr, pu) >= singular_tol


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
    singular_tol: float = 1e-6,
) -> np.ndarray:
    """Maps object trajectories to the task space of eq. 1, angles unwrapped over time.

    Args:
        p_bottle: Bottle positions, shape ``(n_steps, 3)`` [m], world frame.
        a_bottle: Bottle long axes, shape ``(n_steps, 3)``, world frame, any non-zero length.
        p_glass: Glass positions, shape ``(n_steps, 3)`` [m].
        a_glass: Glass long axes, shape ``(n_steps, 3)``.
        gaze: ``R_gaze``, shape ``(3, 3)``, orthonormal, columns (right, up, forward).
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


@dataclass(frozen=True)
class ObjectKinematics:
    """Pose and Jacobians of one held object, optionally batched over leading axes ``...``.

    Attributes:
        position: Object position, shape ``(..., 3)`` [m], world frame.
        axis: Unit long axis, shape ``(..., 3)``, world frame.
        jac_pos: Translational Jacobian ``dp/dq``, shape ``(..., 3, nv)`` [m/rad or m/m].
        jac_rot: Rotational Jacobian (world-frame angular velocity per joint velocity),
            shape ``(..., 3, nv)``.
    """

    position: np.ndarray
    axis: np.ndarray
    jac_pos: np.ndarray
    jac_rot: np.ndarray

    def __post_init__(self) -> None:
        for name in ("position", "axis", "jac_pos", "jac_rot"):
            object.__setattr__(self, name, np.asarray(getattr(self, name), dtype=float))
        batch = self.position.shape[:-1]
        if self.position.shape[-1:] != (3,) or self.axis.shape != self.position.shape:
            raise ImitateError(
                "position and axis must both have shape (..., 3); got "
                f"{self.position.shape} and {self.axis.shape}"
            )
        if self.jac_pos.ndim != len(batch) + 2 or self.jac_pos.shape[:-1] != batch + (3,):
            raise ImitateError(
                f"jac_pos must have shape {batch + (3,)} + (nv,); got {self.jac_pos.shape}"
            )
        if self.jac_rot.shape != self.jac_pos.shape:
            raise ImitateError(
                f"jac_rot must have the shape of jac_pos {self.jac_pos.shape}; "
                f"got {self.jac_rot.shape}"
            )
        if not np.allclose(np.linalg.norm(self.axis, axis=-1), 1.0, atol=1e-6):
            raise ImitateError("axis must be a unit vector (|a| = 1 within 1e-6)")


def task_state(
    bottle: ObjectKinematics,
    glass: ObjectKinematics,
    gaze: ArrayLike,
    *,
    angle_ref: ArrayLike | None = None,
    singular_tol: float = 1e-6,
) -> tuple[np.ndarray, np.ndarray]:
    """Robot-side task-space state ``x(q)`` and Jacobian ``J = dx/dq`` (eq. 1).

    Args:
        bottle: Bottle kinematics, batch shape ``(...)``.
        glass: Glass kinematics, same batch shape and ``nv``.
        gaze: ``R_gaze``, shape ``(3, 3)``.
        angle_ref: Reference angles ``(bottle_angle, glass_angle)``, shape ``(..., 2)`` [rad]:
            each angle is returned on the ``2 pi`` branch nearest to it (e.g. the GMR mean or the
            previous step); ``None`` returns angles in ``(-pi, pi]``.
        singular_tol: Projected axis length below which an angle is undefined (see module).

    Returns:
        ``(x, J)`` of shapes ``(..., 7)`` and ``(..., 7, nv)``.

    Raises:
        ImitateError: On inconsistent shapes, a non-unit axis or a bad gaze frame.
    """
    R = _check_gaze(gaze)
    if bottle.jac_pos.shape != glass.jac_pos.shape:
        raise ImitateError(
            f"bottle and glass Jacobians must have the same shape; got {bottle.jac_pos.shape} "
            f"and {glass.jac_pos.shape}"
        )
    batch = bottle.position.shape[:-1]
    ref = None
    if angle_ref is not None:
        ref = np.asarray(angle_ref, dtype=float)
        if ref.shape != batch + (2,):
            raise ImitateError(f"angle_ref must have shape {batch + (2,)}; got {ref.shape}")
    nv = bottle.jac_pos.shape[-1]
    x = np.empty(batch + (7,))
    J = np.empty(batch + (7, nv))
    x[..., :3] = bottle.position - glass.position
    J[..., :3, :] = bottle.jac_pos - glass.jac_pos
    right, up, forward = R[:, 0], R[:, 1], R[:, 2]
    for n, (obj, col) in enumerate(zip((bottle, glass), _ANGLE_COLUMNS, strict=True)):
        a = obj.axis
        pr, pu, pf = _projections(a, R)
        rho2 = pr * pr + pu * pu
        defined = rho2 >= singular_tol**2
        angle = np.arctan2(pu, pr)
        if ref is not None:
            angle = np.where(defined, angle, ref[..., n])
            angle += 2.0 * np.pi * np.round((ref[..., n] - angle) / (2.0 * np.pi))
        # d(angle) = g . da with g = (pr u - pu r) / rho^2; g . (w x a) = w . (a x g).
        g = (pr[..., None] * up - pu[..., None] * right) / np.where(defined, rho2, 1.0)[..., None]
        g *= defined[..., None]
        x[..., col] = angle
        x[..., col + 1] = pf
        J[..., col, :] = np.einsum("...i,...in->...n", np.cross(a, g), obj.jac_rot)
        J[..., col + 1, :] = np.einsum("...i,...in->...n", np.cross(a, forward), obj.jac_rot)
    return x, J
