"""``Kinematics``: the one owner of the planning ``MjModel``/``MjData`` and of every ``mj_*`` call.

The planner sees the robot as its hinge joints (``joints``, in a fixed order, ``n`` of them) and
the objects it holds as rigid extensions of its hands: every *active* weld equality constraint
whose second body is a free body (a held object) is read once, and each
:meth:`Kinematics.update` sets the object's free joint to the hand's pose composed with the weld's
relative pose (:func:`imitate.motion._planner._hold`) and runs ``mj_kinematics`` a second time, so
no physics runs. Jacobians of points on a held object are ``mj_jac`` of its hand body at that point;
their derivatives along a joint velocity are ``mj_jacDot``.

Jacobians are translational, ``dp/dq`` of points in the world frame, restricted to the
``joints`` columns, shape ``(3, n)`` (orientations enter through points on an object's axis, see
:class:`imitate.motion.taskspace.TaskMap`).
Signed distances come from ``mj_geomDistance`` between the pairs of
:class:`imitate.envs.collision.CollisionPairs`; a compiled test of capsules and slabs enclosing the
geoms (:func:`imitate.motion._planner._near_pairs`) skips the pairs that are far apart first.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from imitate.envs.collision import CollisionPairs
from imitate.errors import ImitateError
from imitate.motion import _planner

__all__ = ["Distances", "Kinematics"]


# Added to ``distmax`` in the near-pair bounds: a pair they skip is at least this much farther
# than ``distmax``, beyond any rounding of mj_geomDistance's convex solver [m].
_SLACK = 1e-4


def _geom_bounds(model: mujoco.MjModel) -> tuple[np.ndarray, np.ndarray]:
    """Per geom, a capsule and a slab that contain it, for
    :func:`imitate.motion._planner._near_pairs`: ``columns (ngeom, 2)``, the frame axes of the
    capsule's segment and of the slab's normal (-1: no slab), and ``sizes (ngeom, 3)``, the
    segment's half-length on either side of the geom's centre, the capsule's radius (``inf``: a
    plane or height field, never skipped) and the slab's half-thickness [m]. A box's capsule
    runs along its longest axis and its slab across its thinnest; a cylinder's slab caps its
    ends."""
    g = mujoco.mjtGeom
    columns = np.full((model.ngeom, 2), (2, -1), dtype=np.intp)
    sizes = np.zeros((model.ngeom, 3))
    sizes[:, 1] = model.geom_rbound  # meshes and others: the bounding sphere
    for i, (kind, size) in enumerate(zip(model.geom_type.tolist(), model.geom_size, strict=True)):
        if kind in (g.mjGEOM_PLANE.value, g.mjGEOM_HFIELD.value):
            sizes[i, 1] = np.inf
        elif kind == g.mjGEOM_SPHERE.value:
            sizes[i, 1] = size[0]
        elif kind == g.mjGEOM_CAPSULE.value:
            sizes[i, :2] = size[1], size[0]
        elif kind == g.mjGEOM_CYLINDER.value:
            columns[i, 1] = 2
            sizes[i] = size[1], size[0], size[1]
        elif kind == g.mjGEOM_BOX.value:
            longest, thinnest = int(np.argmax(size)), int(np.argmin(size))
            others = np.delete(size, longest)
            columns[i] = longest, thinnest
            sizes[i] = size[longest], float(np.hypot(*others)), size[thinnest]
        elif kind == g.mjGEOM_ELLIPSOID.value:
            sizes[i, 1] = float(np.max(size))
    return columns, sizes


@dataclass(frozen=True)
class Distances:
    """Signed distances of the pairs that are closer than a query's ``distmax``.

    Attributes:
        pairs: ``(k,)`` indices into :attr:`Kinematics.pairs`.
        dist: ``(k,)`` signed distances [m], negative when penetrating.
        fromto: ``(k, 6)`` witness points on the first and on the second geom [m], world frame.
        jac: ``(k, n)`` gradients ``dd/dq`` [m/rad], or an empty ``(0, n)`` if not asked for.
    """

    pairs: np.ndarray
    dist: np.ndarray
    fromto: np.ndarray
    jac: np.ndarray


class Kinematics:
    """Forward kinematics, Jacobians and signed distances of the robot and what it holds.

    Args:
        model: The scene; it is not modified. Its active welds to free bodies define what the
            robot holds.
        joints: Names of the hinge joints planned for, ``n`` of them, in the order of ``q``.
        geoms: Geom ids that must keep clear of each other; pairs are filtered by
            :meth:`CollisionPairs.between`. ``None`` for no distance queries.

    Raises:
        ImitateError: On an unknown or non-hinge joint name.
    """

    def __init__(
        self, model: mujoco.MjModel, joints: Sequence[str], geoms: Sequence[int] | None = None
    ):
        self.model = model
        self.data = mujoco.MjData(model)
        names = [model.joint(j).name for j in range(model.njnt)]
        ids = []
        for name in joints:
            if name not in names:
                raise ImitateError(f"joint {name!r} unknown; accepted: {names}")
            jid = model.joint(name).id
            if model.jnt_type[jid] != mujoco.mjtJoint.mjJNT_HINGE:
                raise ImitateError(f"joint {name!r} is not a hinge joint; only hinges are planned")
            ids.append(jid)
        self.joints = tuple(joints)
        self.qpos_adr = model.jnt_qposadr[ids].copy()
        self.dof_adr = model.jnt_dofadr[ids].copy()
        # Where q goes in qpos and qvel: a slice when the joints are consecutive (faster).
        self._q_index, self._dof_index = (
            slice(int(adr[0]), int(adr[0]) + len(adr))
            if len(adr) and np.array_equal(adr, np.arange(adr[0], adr[0] + len(adr)))
            else adr
            for adr in (self.qpos_adr, self.dof_adr)
        )
        self.lower, self.upper = model.jnt_range[ids].T.copy()
        self.span = self.upper - self.lower  # the joints' full ranges [rad], however narrowed
        self._held = self._held_objects()
        owner = np.arange(model.nbody)  # body whose Jacobian moves each body
        for obj, (hand, _, _) in self._held.items():
            owner[obj] = hand
        self._owners = owner.tolist()  # a list, for the inner loops
        self.pairs = CollisionPairs.between(model, geoms) if geoms is not None else None
        self._geom_body = model.geom_bodyid.tolist()
        d = self.data
        if self.pairs is not None:
            self._pair_geoms = (self.pairs.geom1.tolist(), self.pairs.geom2.tolist())
            geom1, geom2 = (np.ascontiguousarray(g, dtype=np.intp) for g in self._pair_geoms)
            # _near_pairs' arguments but the range and the output
            self._near_args = (d.geom_xpos, d.geom_xmat, geom1, geom2, *_geom_bounds(model))
            self._near = np.empty(len(self.pairs), dtype=np.intp)
            self._fromto = np.zeros((len(self.pairs), 6))
            self._none_near = Distances(  # shared by the queries that find no pair (read only)
                np.zeros(0, dtype=int), np.zeros(0), np.zeros((0, 6)), np.zeros((0, len(ids)))
            )
        # Views kept once: MjData attribute access builds a new array each time.
        self._qpos, self._qvel = d.qpos, d.qvel
        # Per held object: its hand and free joint's qpos address; its weld pose.
        self._held_args = (
            np.array(
                [(hand, model.jnt_qposadr[model.body_jntadr[obj]])
                 for obj, (hand, _, _) in self._held.items()],
                dtype=np.intp,
            ).reshape(-1, 2),
            np.array([np.concatenate(pose) for _, *pose in self._held.values()]).reshape(-1, 7),
            d.qpos, d.xpos, d.xquat,
        )
        self._jacp = np.zeros((4, 3, model.nv))

    @property
    def n(self) -> int:
        """Number of planned joints."""
        return len(self.joints)

    def _held_objects(self) -> dict[int, tuple[int, np.ndarray, np.ndarray]]:
        """``{object body: (hand body, relative position (3,), relative quaternion (4,))}``."""
        m = self.model
        held = {}
        for e in range(m.neq):
            if m.eq_type[e] != mujoco.mjtEq.mjEQ_WELD or not m.eq_active0[e]:
                continue
            hand, obj = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
            jnt = m.body_jntadr[obj]
            if jnt < 0 or m.jnt_type[jnt] != mujoco.mjtJoint.mjJNT_FREE:
                continue
            held[obj] = (hand, m.eq_data[e, 3:6].copy(), m.eq_data[e, 6:10].copy())
        return held

    def update(self, q: np.ndarray, held: bool = True) -> None:
        """Sets the joint angles ``q`` ``(n,)`` [rad] and updates all body and geom poses (no
        physics); ``held=False`` leaves the held objects where they were (enough for Jacobians
        of points given in the world frame)."""
        self._qpos[self._q_index] = q
        self._place(held)

    def update_between(self, qa: np.ndarray, qb: np.ndarray, s: float) -> None:
        """:meth:`update` to ``(1 - s) qa + s qb`` (``qa``, ``qb`` ``(n,)`` [rad]), the posture
        at ``s`` along a straight step, formed in a compiled kernel."""
        _planner._lerp(qa, qb, s, self._qpos, self.qpos_adr)
        self._place(True)

    def _place(self, held: bool) -> None:
        """Body and geom poses, and the held objects' if ``held``, at the set ``qpos``."""
        m, d = self.model, self.data
        mujoco.mj_kinematics(m, d)
        if held and self._held:
            _planner._hold(*self._held_args)
            mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)

    def camera_pose(self, camera: str) -> tuple[np.ndarray, np.ndarray]:
        """World pose of ``camera``: ``(pos (3,) [m], R (3, 3))``, columns its x, y, z axes."""
        mujoco.mj_camlight(self.model, self.data)
        c = self.model.camera(camera).id
        return self.data.cam_xpos[c].copy(), self.data.cam_xmat[c].reshape(3, 3).copy()

    def point_jacobians(
        self, bodies: Sequence[int], points: np.ndarray, out: np.ndarray | None = None
    ) -> np.ndarray:
        """Translational Jacobians ``(k, 3, n)`` [m/rad] of ``k <= 4`` points ``(k, 3)`` [m]
        fixed to ``bodies`` (ids; held objects move with their hands); into ``out`` if given."""
        m, d, jacp, owner = self.model, self.data, self._jacp, self._owners
        for k, (b, p) in enumerate(zip(bodies, points, strict=True)):
            mujoco.mj_jac(m, d, jacp[k], None, p, owner[b])
        return jacp[: len(bodies)].take(self.dof_adr, axis=2, out=out)

    def frame_jacobians(
        self, bodies: Sequence[int], points: np.ndarray, out: np.ndarray
    ) -> np.ndarray:
        """Translational and rotational Jacobians of ``k`` points ``(k, 3)`` [m] fixed to
        ``bodies`` (ids; held objects move with their hands), all ``nv`` columns, into ``out``
        ``(k, 2, 3, nv)``. The planned joints are the columns :attr:`dof_adr`."""
        m, d, owner = self.model, self.data, self._owners
        for k, b in enumerate(bodies):
            mujoco.mj_jac(m, d, out[k, 0], out[k, 1], points[k], owner[b])
        return out

    def frame_jacobian_rates(
        self, bodies: Sequence[int], points: np.ndarray, qdots: Sequence[np.ndarray],
        out: np.ndarray,
    ) -> np.ndarray:
        """Derivatives of :meth:`frame_jacobians` along each joint velocity of ``qdots``
        (``(n,)`` each [rad/s]; ``mj_comVel``, ``mj_jacDot``), into ``out``
        ``(len(qdots), k, 2, 3, nv)``."""
        m, d, owner = self.model, self.data, self._owners
        for i, qdot in enumerate(qdots):
            self._qvel[self._dof_index] = qdot
            mujoco.mj_comVel(m, d)
            for k, b in enumerate(bodies):
                mujoco.mj_jacDot(m, d, out[i, k, 0], out[i, k, 1], points[k], owner[b])
        return out

    def point_jacobian_rates(
        self,
        bodies: Sequence[int],
        points: np.ndarray,
        qdot: np.ndarray,
        out: np.ndarray | None = None,
    ) -> np.ndarray:
        """Derivatives ``(k, 3, n)`` [m/rad^2] of :meth:`point_jacobians` along the joint
        velocity ``qdot`` ``(n,)`` [rad/s] (``mj_comVel``, ``mj_jacDot``), the points moving
        with their bodies; into ``out`` if given."""
        m, d, jacp, owner = self.model, self.data, self._jacp, self._owners
        self._qvel[self._dof_index] = qdot
        mujoco.mj_comVel(m, d)
        for k, (b, p) in enumerate(zip(bodies, points, strict=True)):
            mujoco.mj_jacDot(m, d, jacp[k], None, p, owner[b])
        return jacp[: len(bodies)].take(self.dof_adr, axis=2, out=out)

    def distances(self, distmax: float, *, jacobian: bool = False) -> Distances:
        """Signed distances of the pairs closer than ``distmax`` [m] at the last :meth:`update`.

        Args:
            distmax: Pairs whose bounding spheres are farther apart than this are skipped, and
                those found farther are dropped.
            jacobian: Also compute ``dd/dq`` for each returned pair.

        Raises:
            ImitateError: If the kinematics were built without ``geoms``.
        """
        if self.pairs is None:
            raise ImitateError("distances need the Kinematics to be built with geoms")
        count = _planner._near_pairs(*self._near_args, distmax + _SLACK, self._near)
        if not count:
            return self._none_near
        m, d = self.model, self.data
        g1, g2 = self._pair_geoms
        near = self._near[:count].tolist()
        kept: list[int] = []
        dist: list[float] = []
        fromto, geom_distance = self._fromto, mujoco.mj_geomDistance
        for p in near:
            value = geom_distance(m, d, g1[p], g2[p], distmax, fromto[len(kept)])
            if value < distmax:
                kept.append(p)
                dist.append(value)
        if not kept:
            return self._none_near
        fromto = fromto[: len(kept)].copy()
        jac = np.zeros((len(kept), self.n))
        if jacobian:
            for k, p in enumerate(kept):
                jac[k] = self._distance_gradient(g1[p], g2[p], dist[k], fromto[k])
        return Distances(np.array(kept, dtype=int), np.array(dist), fromto, jac)

    def _distance_gradient(self, g1: int, g2: int, dist: float, fromto: np.ndarray) -> np.ndarray:
        """``dd/dq`` ``(n,)`` = ``n^T (J(p2) - J(p1))``; ``n`` flips when penetrating."""
        gap = fromto[3:] - fromto[:3]
        norm = math.sqrt(gap.dot(gap))  # np.linalg.norm's arithmetic
        if norm < 1e-12:
            return np.zeros(self.n)
        normal = (-gap if dist < 0 else gap) / norm
        j1, j2 = self.point_jacobians(
            (self._geom_body[g1], self._geom_body[g2]), fromto.reshape(2, 3)
        )
        return normal @ (j2 - j1)

    def min_distance(self, distmax: float = 0.2) -> tuple[float, tuple[str, str] | None]:
        """Smallest signed distance [m] over all pairs (``distmax`` if none is closer) and the
        names of its geoms (``None`` if none is closer)."""
        result = self.distances(distmax)
        if len(result.dist) == 0:
            return distmax, None
        k = int(np.argmin(result.dist))
        assert self.pairs is not None  # else distances() raised
        return float(result.dist[k]), self.pairs.names(self.model, int(result.pairs[k]))
