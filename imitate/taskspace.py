r"""Task spaces: a small vocabulary of terms, eq. 1 among them, the gaze frame, and the map of
object trajectories.

A bimanual task moves a **tool** (held by the right hand) to a **target** (held by the left),
possibly relative to **places** in the scene (bodies the robot does not move, named by their
body names). A task declares its space (:class:`TaskSpace`) as a sequence of terms:

- :class:`Relative` ``(of, to)``: ``p_of - p_to`` in the world frame, 3 columns ``dx, dy, dz``
  [m], tolerance 1 cm each; ``Relative(of, to, frame)`` the same in a held object's own frame
  (:func:`own_frame`);
- :class:`Angles` ``(of)``: the held object's long axis ``a`` seen from the gaze, 2 columns:
  ``angle = atan2(a . d, a . r)`` [rad] (clockwise in the image, see below; tolerance 2 deg) and
  ``gaze = a . f`` [1] (tolerance 0.05).

Eq. 1 of the paper, :data:`EQ1`, is ``(Relative("tool", "target"), Angles("tool"),
Angles("target"))``, 7 columns:

=====  ==================  =====  ==================================================================
index  name                unit   meaning
=====  ==================  =====  ==================================================================
0-2    ``dx, dy, dz``      m      ``p_tool - p_target`` in the world frame
3      ``tool_angle``      rad    angle of the tool's long axis projected onto the image plane
4      ``tool_gaze``       1      component of the tool's long axis along the gaze, ``a . f``
5      ``target_angle``    rad    as 3, for the target
6      ``target_gaze``     1      as 4, for the target
=====  ==================  =====  ==================================================================

A space maps observed trajectories (positions and long axes) to demonstrations
(:meth:`TaskSpace.__call__`); the robot's map of its joint angles
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

An object's own frame: the objects are symmetric about their long axes, so an axis fixes a frame
up to a turn about it, which the gaze fixes: ``z = a``, ``x`` the gaze's forward ``f`` made
perpendicular to ``a`` (``f - (f . a) a``, normalised), ``y = z x x``. Where ``a`` lies along
the gaze (``|a x f|`` below :data:`SINGULAR_TOL`) the camera's right ``r`` takes ``f``'s place
(:func:`frame_reference`), on the demonstrations and on the robot alike.

Singularity: when the axis is (nearly) parallel to the gaze its projection
``rho = hypot(a . r, a . d)`` vanishes and the angle is undefined. Below :data:`SINGULAR_TOL`
the demonstration map holds the last defined angle (the first defined one before it, 0 if none
is defined), and the robot map returns ``angle_ref`` with a zero Jacobian row, so an optimizer
neither chases nor is thrown by an undefined quantity; the ``a . f`` component stays defined.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from imitate.errors import ImitateError

__all__ = [
    "EQ1",
    "OBJECTS",
    "SINGULAR_TOL",
    "Angles",
    "Relative",
    "WORLD",
    "TaskSpace",
    "check_gaze",
    "gaze_frame",
    "gaze_of_camera",
    "frame_reference",
    "image_angle",
    "object_orientation",
    "own_frame",
]

OBJECTS = ("tool", "target")  # the held objects' roles; any other name in a term is a place
WORLD = "world"  # the place every scene has: the world's origin, MuJoCo's world body
# Projected length ``rho`` of a unit axis onto the image plane below which its angle is
# undefined (the axis lies within about 1e-6 rad of the gaze).
SINGULAR_TOL = 1e-6


@dataclass(frozen=True)
class Relative:
    """``p_of - p_to`` [m], 3 columns, in the world frame, or with ``frame`` (a role of
    :data:`OBJECTS`) in that object's own frame (:func:`own_frame`). ``of`` and ``to`` are roles
    of :data:`OBJECTS` or places (body names), not the same."""

    of: str
    to: str
    frame: str | None = None
    units = ("m", "m", "m")
    tolerance = (0.01, 0.01, 0.01)

    @property
    def name(self) -> str:
        """``OF-TO``, and ``@FRAME`` in an object's frame: ``tool-target@target``."""
        return f"{self.of}-{self.to}" + (f"@{self.frame}" if self.frame else "")

    def labels(self, names: Mapping[str, str], alone: bool) -> tuple[str, ...]:
        """``dx, dy, dz``, or, unless ``alone`` (the space's only position),
        ``<of>_<to>_dx, ...`` in the task's words ``names`` (role -> name); ``..._in_<frame>``
        in an object's frame."""
        prefix = "" if alone else f"{names.get(self.of, self.of)}_{names.get(self.to, self.to)}_"
        suffix = f"_in_{names.get(self.frame, self.frame)}" if self.frame else ""
        return tuple(f"{prefix}d{c}{suffix}" for c in "xyz")


@dataclass(frozen=True)
class Angles:
    """A held object's orientation as eq. 1 has it: the image angle of its long axis [rad] and
    the axis' component along the gaze [1]. ``of`` is a role of :data:`OBJECTS`."""

    of: str
    units = ("rad", "1")
    tolerance = (float(np.radians(2.0)), 0.05)

    def labels(self, names: Mapping[str, str], alone: bool) -> tuple[str, ...]:
        """``<of>_angle, <of>_gaze`` in the task's words ``names`` (role -> name)."""
        name = names.get(self.of, self.of)
        return f"{name}_angle", f"{name}_gaze"


Term = Relative | Angles


@dataclass(frozen=True)
class TaskSpace:
    """A task space: its terms' columns side by side (see the module docstring).

    Attributes:
        terms: The terms, in column order; each object has at most one :class:`Angles`.

    Raises:
        ImitateError: No term, an :class:`Angles` of a place or twice of one object, or a
            :class:`Relative` of a name to itself.
    """

    terms: tuple[Term, ...]

    def __post_init__(self) -> None:
        angled = [t.of for t in self.terms if isinstance(t, Angles)]
        if not self.terms or not all(isinstance(t, Relative | Angles) for t in self.terms):
            raise ImitateError(f"a task space needs terms Relative or Angles; got {self.terms}")
        if set(angled) - set(OBJECTS) or len(set(angled)) < len(angled):
            raise ImitateError(f"Angles are of the held objects {OBJECTS}, once each; got {angled}")
        relations = [t for t in self.terms if isinstance(t, Relative)]
        if any(t.of == t.to for t in relations):
            raise ImitateError(f"a Relative term needs two names; got {self.terms}")
        if any(t.frame not in (None, *OBJECTS) for t in relations):
            raise ImitateError(f"a Relative's frame is a held object of {OBJECTS} or none (the "
                               f"world's); got {[t.frame for t in relations]}")
        if not self.positions:
            raise ImitateError(f"a task space needs a Relative term; got {self.terms}")

    @property
    def starts(self) -> tuple[int, ...]:
        """Each term's first column."""
        widths = [len(t.units) for t in self.terms]
        return tuple(int(s) for s in np.cumsum([0, *widths[:-1]]))

    @property
    def m(self) -> int:
        """The number of columns."""
        return sum(len(t.units) for t in self.terms)

    @property
    def units(self) -> tuple[str, ...]:
        """Each column's unit."""
        return tuple(u for t in self.terms for u in t.units)

    @property
    def tolerance(self) -> np.ndarray:
        """``(m,)`` each column's tolerance, in its unit: the error that matters (1 cm, 2 deg,
        0.05); eq. 21's weight at zero variance is ``1 / tolerance^2``."""
        return np.array([v for t in self.terms for v in t.tolerance])

    @property
    def places(self) -> tuple[str, ...]:
        """The places its terms name (neither held object), in order of appearance."""
        names = [n for t in self.terms if isinstance(t, Relative) for n in (t.of, t.to)]
        return tuple(dict.fromkeys(n for n in names if n not in OBJECTS))

    def columns(self, term: Term) -> slice:
        """The columns of ``term``.

        Raises:
            ImitateError: ``term`` is not one of the space's.
        """
        if term not in self.terms:
            raise ImitateError(f"{term} is not a term of the task space {self.terms}")
        start = self.starts[self.terms.index(term)]
        return slice(start, start + len(term.units))

    def part_columns(self, part: TaskSpace) -> np.ndarray:
        """The columns that hold ``part``'s terms, in ``part``'s order.

        Raises:
            ImitateError: a term of ``part`` is not one of the space's.
        """
        return np.concatenate([np.arange(c.start, c.stop) for c in map(self.columns, part.terms)])

    @property
    def positions(self) -> tuple[slice, ...]:
        """The columns of each :class:`Relative` [m]; the first is the task's main one."""
        return tuple(slice(s, s + 3) for t, s in zip(self.terms, self.starts, strict=True)
                     if isinstance(t, Relative))

    @property
    def position_columns(self) -> np.ndarray:
        """``(3 k,)`` the columns of every :class:`Relative` [m]."""
        return np.concatenate([np.arange(p.start, p.stop) for p in self.positions])

    def distance(self, x: np.ndarray) -> np.ndarray:
        """``(...)`` the largest length over the :class:`Relative` terms of task vectors ``x``
        ``(..., m)`` [m] (of errors or changes: how far the positions are off)."""
        return np.max([np.linalg.norm(x[..., p], axis=-1) for p in self.positions], axis=0)

    @property
    def angles(self) -> np.ndarray:
        """``(k,)`` the angle columns [rad], one per :class:`Angles`, read-only."""
        cols = np.array([s for t, s in zip(self.terms, self.starts, strict=True)
                         if isinstance(t, Angles)], dtype=int)
        cols.flags.writeable = False
        return cols

    def angle_ref(self, x: np.ndarray) -> np.ndarray:
        """``(..., 2)`` the tool's and the target's angles in task states ``x`` ``(..., m)``
        [rad]; 0 for an object without :class:`Angles` (the robot map's branch references)."""
        ref = np.zeros((*x.shape[:-1], len(OBJECTS)))
        for t, s in zip(self.terms, self.starts, strict=True):
            if isinstance(t, Angles):
                ref[..., OBJECTS.index(t.of)] = x[..., s]
        return ref

    @property
    def text(self) -> tuple[str, ...]:
        """Its terms as text, ``("tool-target", "tool angles", ...)``: what a run stores
        (:meth:`from_text` reads it back)."""
        return tuple(t.name if isinstance(t, Relative) else f"{t.of} angles" for t in self.terms)

    @classmethod
    def from_text(cls, text: Sequence[str]) -> TaskSpace:
        """The space whose :attr:`text` is ``text``.

        Raises:
            ImitateError: a term not in that form.
        """
        terms: list[Term] = []
        for item in text:
            words = str(item).split(" ")
            relation, _, frame = words[0].partition("@")
            ends = relation.split("-")
            if len(words) == 2 and words[1] == "angles":
                terms.append(Angles(words[0]))
            elif len(words) == 1 and len(ends) == 2:
                terms.append(Relative(ends[0], ends[1], frame or None))
            else:
                raise ImitateError(f"task space term {item!r} not accepted: 'OF-TO', "
                                   "'OF-TO@FRAME' or 'OF angles'")
        return cls(tuple(terms))

    def labels(self, names: Mapping[str, str] | None = None) -> tuple[str, ...]:
        """Each column's label in the task's words ``names`` (role -> name: ``{"tool":
        "bottle"}``), the roles themselves where not given."""
        alone = len(self.positions) == 1
        return tuple(c for t in self.terms for c in t.labels(names or {}, alone))

    def __call__(
        self,
        tracks: Mapping[str, tuple[ArrayLike, ArrayLike | None]],
        gaze: ArrayLike,
        *,
        singular_tol: float = SINGULAR_TOL,
    ) -> np.ndarray:
        """Maps observed trajectories to this space, angles unwrapped over time.

        Args:
            tracks: By role or place: ``(positions (n_steps, 3) [m], long axes (n_steps, 3))``
                in the world frame, any non-zero axis length; a place's axes may be ``None``;
                :data:`WORLD` needs none (it is the origin).
            gaze: ``R_gaze``, shape ``(3, 3)``, right-handed, columns (right, down, forward).
            singular_tol: Projected axis length below which an angle is undefined and held.

        Returns:
            ``x``, shape ``(n_steps, m)``, in the units of :attr:`units`.

        Raises:
            ImitateError: On a missing track, mismatched shapes, non-finite values, zero axes
                or a bad gaze frame.
        """
        if WORLD in self.places and WORLD not in tracks:
            first = np.asarray(next(iter(tracks.values()))[0], dtype=float)
            tracks = {**tracks, WORLD: (np.zeros_like(first), None)}
        missing = sorted({n for t in self.terms for n in vars(t).values() if n} - set(tracks))
        if missing:
            raise ImitateError(f"no track of {missing}; given: {sorted(tracks)}")
        position = {name: np.asarray(p, dtype=float) for name, (p, _) in tracks.items()}
        axes = {name: np.asarray(a, dtype=float) for name, (_, a) in tracks.items()
                if a is not None}
        shape = next(iter(position.values())).shape
        if len(shape) != 2 or shape[1] != 3 or shape[0] == 0:
            raise ImitateError(f"positions must have shape (n_steps, 3); got {shape}")
        for what, arrays in (("positions", position), ("axes", axes)):
            for name, arr in arrays.items():
                if arr.shape != shape:
                    raise ImitateError(f"{name} {what} must have shape {shape}; got {arr.shape}")
                if not np.all(np.isfinite(arr)):
                    raise ImitateError(f"{name} {what} must be finite (no NaN or inf)")

        def axes_of(name: str) -> np.ndarray:
            if name not in axes:
                raise ImitateError(f"{name} needs its long axes for its angles or its frame")
            return axes[name]

        x = np.empty((shape[0], self.m))
        for term, s in zip(self.terms, self.starts, strict=True):
            if isinstance(term, Relative):
                p = position[term.of] - position[term.to]
                if term.frame:
                    p = (own_frame(axes_of(term.frame), gaze) @ p[:, :, None])[:, :, 0]
                x[:, s : s + 3] = p
                continue
            angle, along, defined = object_orientation(axes_of(term.of), gaze,
                                                       singular_tol=singular_tol)
            x[:, s] = np.unwrap(_hold_undefined(angle, defined))
            x[:, s + 1] = along
        return x


EQ1 = TaskSpace((Relative("tool", "target"), Angles("tool"), Angles("target")))  # the paper's


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
    c = _unit(axis) @ R
    return _angle(c), c[..., 2], np.hypot(c[..., 0], c[..., 1]) >= singular_tol


def frame_reference(axis: np.ndarray, gaze: np.ndarray) -> np.ndarray:
    """``(...)`` the column of ``gaze`` (``R_gaze``) that fixes the own frame of objects with
    unit long axes ``axis`` ``(..., 3)`` about them: 2 (forward), or 0 (right) where the axis
    lies along the gaze (see the module)."""
    along = np.linalg.norm(np.cross(axis, gaze[:, 2]), axis=-1) < SINGULAR_TOL
    return np.where(along, 0, 2)


def own_frame(axis: ArrayLike, gaze: ArrayLike) -> np.ndarray:
    """Objects' own frames from their long axes (see the module).

    Args:
        axis: Long axes in the world frame, shape ``(..., 3)``; normalised here, non-zero.
        gaze: ``R_gaze``, shape ``(3, 3)``.

    Returns:
        ``(..., 3, 3)``: rows ``x, y, z`` in world coordinates, so ``frame @ v`` is ``v`` in
        the object's frame.

    Raises:
        ImitateError: On a zero or non-finite axis or a bad gaze frame.
    """
    R, a = check_gaze(gaze), _unit(axis)
    g = R.T[frame_reference(a, R)]
    u = g - np.sum(g * a, axis=-1, keepdims=True) * a
    x = u / np.linalg.norm(u, axis=-1, keepdims=True)
    return np.stack((x, np.cross(a, x), a), axis=-2)


def _unit(axis: ArrayLike) -> np.ndarray:
    """Long axes ``(..., 3)`` normalised.

    Raises:
        ImitateError: On a zero or non-finite axis, or one not of 3 components.
    """
    a = np.asarray(axis, dtype=float)
    norm = np.linalg.norm(a, axis=-1)
    if a.shape[-1:] != (3,) or not np.all(np.isfinite(a)) or np.any(norm == 0.0):
        raise ImitateError(
            f"axis must be finite non-zero vectors of shape (..., 3); got shape {a.shape}"
        )
    return a / norm[..., None]


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
