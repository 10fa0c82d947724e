r"""Whole-body resolved motion rate control (RMR): task trajectory -> joint trajectory.

Per step ``t`` (``n`` joints, ``m`` task dimensions):

.. math::
    J^\# = W^{-1} J^T (J W^{-1} J^T + \lambda I)^{-1}, \qquad
    q_{t+1} = q_t + J^\# (x_{t+1} - \phi(q_t)) - \alpha (I - J^\# J) W^{-1} \nabla H(q_t)

with the joint metric ``W^{-1} = diag(range_i)`` (zero for joints the task must not drive, the
head) and the joint-limit "border" cost ``H`` (zero in a free zone around each range's centre,
quadratic outside it). ``q`` is clipped to the joint ranges, and each clip is counted.

The task map ``phi`` is eq. 1 (:mod:`imitate.taskspace`) evaluated on the held objects; it is
re-implemented here without input validation because it runs in the inner loop, and a test keeps
it equal to :func:`imitate.taskspace.task_state`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg.lapack import dposv

from imitate.errors import ImitateError
from imitate.kinematics import Distances, Kinematics

__all__ = [
    "ControlConfig", "JointLimitCost", "Rollout", "TaskFrame", "TaskMap", "backward", "reach",
    "rollout",
]


@dataclass(frozen=True)
class ControlConfig:
    """Parameters of the RMR rollout.

    Attributes:
        damping: ``lambda`` added to ``J W^-1 J^T`` [task units^2 rad]; keeps ``J^#`` bounded
            near singularities.
        nullspace_gain: ``alpha``, fraction of the joint-limit gradient step taken per step.
        free_ratio: Fraction of each half range around the centre where ``H`` is zero.
        fixed_joints: Joints the task does not drive (kept at their start angle).
    """

    damping: float = 1e-4
    nullspace_gain: float = 0.05
    free_ratio: float = 0.7
    fixed_joints: tuple[str, ...] = ("head_pan", "head_tilt")

    def __post_init__(self):
        if not self.damping > 0 or not self.nullspace_gain >= 0 or not 0 <= self.free_ratio < 1:
            raise ImitateError(
                f"ControlConfig needs damping > 0, nullspace_gain >= 0, 0 <= free_ratio < 1; got "
                f"{self.damping}, {self.nullspace_gain}, {self.free_ratio}"
            )


class JointLimitCost:
    r"""Border joint-limit cost ``H(q) = 1/2 sum_i ((q_i - b_i) / p_i)^2`` outside the free zone.

    ``b_i`` is the free zone's border on the side ``q_i`` is on, ``p_i`` the penalty range
    between the border and the limit. Its Hessian is diagonal.
    """

    def __init__(self, lower: np.ndarray, upper: np.ndarray, free_ratio: float):
        centre, half = 0.5 * (lower + upper), 0.5 * (upper - lower)
        self.low_border, self.high_border = centre - free_ratio * half, centre + free_ratio * half
        self.scale = 1.0 / ((1.0 - free_ratio) * half) ** 2

    def __call__(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(H (...,), dH/dq (..., n), diag d2H/dq2 (..., n))`` for ``q`` of shape ``(..., n)``."""
        excess = np.minimum(q - self.low_border, 0.0) + np.maximum(q - self.high_border, 0.0)
        grad = self.scale * excess
        return 0.5 * np.sum(grad * excess, axis=-1), grad, self.scale * (excess != 0.0)

    def gradient(self, q: np.ndarray) -> np.ndarray:
        """``dH/dq`` ``(n,)`` alone, for ``q`` ``(n,)`` (the rollout's inner loop)."""
        low, high = np.minimum(q - self.low_border, 0.0), np.maximum(q - self.high_border, 0.0)
        return self.scale * (low + high)


class TaskMap:
    r"""Eq. 1 on the robot: ``x = (p_b - p_g, phi_b, phi_g)`` and ``J = dx/dq`` ``(7, n)``.

    An object's angle and gaze-forward component depend on its long axis ``a`` only:
    ``d(angle, forward) = C R_gaze^T da`` with ``C = [[-p_u, p_r, 0] / rho^2, [0, 0, 1]]``
    (``p = R_gaze^T a``, ``rho^2 = p_r^2 + p_u^2``). ``A = da/dq`` ``(3, n)`` is the Jacobian of
    the point ``o + a`` minus that of the origin ``o``, so every row of ``J`` and of its
    derivative along ``b`` (:meth:`rates`: ``C' R_gaze^T A + C R_gaze^T A'``) comes from
    ``mj_jac`` and ``mj_jacDot`` of the four points ``o_b, o_g, o_b + a_b, o_g + a_g``.

    Args:
        kin: The kinematics (its held objects give the bottle and glass poses).
        bottle, glass: Body names of the two objects.
        gaze: ``R_gaze`` ``(3, 3)``, columns camera right, up, forward, fixed in the world.
        fixed_joints: Joints whose Jacobian columns are zeroed.
    """

    m = 7

    def __init__(
        self,
        kin: Kinematics,
        bottle: str,
        glass: str,
        gaze: np.ndarray,
        fixed_joints: Sequence[str] = (),
    ):
        self.kin = kin
        self.bottle, self.glass = kin.model.body(bottle).id, kin.model.body(glass).id
        self.gaze = np.asarray(gaze, dtype=float)
        unknown = sorted(set(fixed_joints) - set(kin.joints))
        if unknown:
            raise ImitateError(f"fixed_joints {unknown} unknown; accepted: {list(kin.joints)}")
        self.driven = np.array([j not in fixed_joints for j in kin.joints])
        self._bodies = np.array([self.bottle, self.glass])
        self._points_of = (self.bottle, self.glass, self.bottle, self.glass)
        self._gaze_t = np.ascontiguousarray(self.gaze.T)
        self._mask = self.driven.astype(float)
        self._xpos, self._xmat = kin.data.xpos, kin.data.xmat  # views, kept once
        self._ru = np.ascontiguousarray(self.gaze[:, :2].T)  # (2, 3) gaze right, up
        self._right, self._up = self._ru.tolist()
        # evaluate's (7, 12) map from the four points' Jacobians to J, constant rows filled.
        self._mix = np.zeros((7, 12))
        self._mix[:3, :3], self._mix[:3, 3:6] = np.eye(3), -np.eye(3)
        forward = self.gaze[:, 2]
        self._mix[4, 6:9], self._mix[4, :3] = forward, -forward
        self._mix[6, 9:12], self._mix[6, 3:6] = forward, -forward
        self._rate = np.empty((2, 12, kin.n))  # curvature's buffer

    def __call__(self, angle_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(x (7,), J (7, n))`` at the kinematics' last update; angles on the branch nearest to
        ``angle_ref`` ``(2,)`` [rad]."""
        x, J, _ = self.evaluate(angle_ref)
        return x, J

    def evaluate(self, angle_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray, TaskFrame]:
        """As :meth:`__call__`, and the :class:`TaskFrame` that :meth:`rates` needs."""
        points = np.empty((4, 3))
        self._xpos.take(self._bodies, axis=0, out=points[:2])
        axis = self._xmat.take(self._bodies, axis=0)[:, 2::3]
        points[2:] = points[:2] + axis
        proj = axis @ self.gaze
        x = (points[0] - points[1]).tolist()
        inv = []
        mix = self._mix.copy()
        right, up = self._right, self._up
        objects = zip(proj.tolist(), angle_ref.tolist(), strict=True)
        for o, ((pr, pu, pf), ref) in enumerate(objects):
            angle = math.atan2(pu, pr)
            x += (angle + 2.0 * math.pi * round((ref - angle) / (2.0 * math.pi)), pf)
            rho2 = pr * pr + pu * pu
            s = 1.0 / rho2 if rho2 > 1e-12 else 0.0
            inv.append(s)
            row = [-pu * s * ri + pr * s * ui for ri, ui in zip(right, up, strict=True)]
            mix[3 + 2 * o, 6 + 3 * o : 9 + 3 * o] = row
            mix[3 + 2 * o, 3 * o : 3 + 3 * o] = [-v for v in row]
        jac = self.kin.point_jacobians(self._points_of, points)
        J = mix @ jac.reshape(12, -1)
        J *= self._mask
        frame = TaskFrame(points, proj, np.array(inv), mix, jac[2:] - jac[:2])
        return np.array(x), J, frame

    def rates(self, qdot: np.ndarray, frame: TaskFrame) -> np.ndarray:
        """``D_b J`` ``(k, 7, n)``: derivatives of ``J`` along each joint direction ``b`` in
        ``qdot`` ``(k, n)`` [rad], at the posture of ``frame`` (from :meth:`evaluate`), which the
        kinematics must be updated to (held objects may be left out)."""
        n = self.kin.n
        rate = np.empty((len(qdot), 12, n))
        for k, b in enumerate(qdot):
            rate[k] = self.kin.point_jacobian_rates(self._points_of, frame.points, b).reshape(12, n)
        # C' (only its angle row moves): d(-p_u s, p_r s) with s = 1 / rho^2, p' = R^T A b.
        dproj = self._gaze_t @ (frame.axis_jac @ qdot.T)  # (2, 3, k)
        (pr, pu), s = frame.proj[:, :2, None].transpose(1, 0, 2), frame.inv[:, None]
        ds = -2.0 * (pr * dproj[:, 0] + pu * dproj[:, 1]) * s * s  # (2, k)
        r, u, _ = self.gaze.T
        coef_r, coef_u = -dproj[:, 1] * s - pu * ds, dproj[:, 0] * s + pr * ds  # (2, k)
        row_dot = coef_r[..., None] * r + coef_u[..., None] * u  # (2, k, 3)
        out = frame.mix @ rate
        out[:, 3::2] += (row_dot @ frame.axis_jac).transpose(1, 0, 2)
        out *= self._mask
        return out

    def curvature(
        self, a: np.ndarray, b: np.ndarray, c: np.ndarray, d: np.ndarray, frame: TaskFrame
    ) -> np.ndarray:
        """``a^T D_b J + c^T D_d J`` ``(n,)`` for task vectors ``a, c`` ``(7,)`` and joint
        directions ``b, d`` ``(n,)`` [rad]: two contractions of :meth:`rates` without forming
        ``D J`` (one weighted sum of the points' ``mj_jacDot`` and one of the axis Jacobians for
        the ``C'`` term). Same preconditions as :meth:`rates`."""
        kin, rate = self.kin, self._rate
        rate[0] = kin.point_jacobian_rates(self._points_of, frame.points, b).reshape(12, -1)
        rate[1] = kin.point_jacobian_rates(self._points_of, frame.points, d).reshape(12, -1)
        left = np.array((a, c))
        out = (left @ frame.mix).ravel() @ rate.reshape(24, -1)
        # C' term of the angle rows 3 and 5, as in :meth:`rates`, weighted by a and c.
        axis_jac = frame.axis_jac.reshape(6, -1)
        dproj = (self._ru @ (axis_jac @ np.array((b, d)).T).reshape(2, 3, 2)).tolist()
        weights = left[:, 3::2].T.tolist()  # (2 objects, 2 directions)
        coef = []
        for (pr, pu, _), s, (dpr, dpu), w in zip(
            frame.proj.tolist(), frame.inv.tolist(), dproj, weights, strict=True
        ):
            cr = cu = 0.0
            for dr, du, wk in zip(dpr, dpu, w, strict=True):
                ds = -2.0 * (pr * dr + pu * du) * s * s
                cr += wk * (-du * s - pu * ds)
                cu += wk * (dr * s + pr * ds)
            coef.append((cr, cu))
        out += (np.array(coef) @ self._ru).ravel() @ axis_jac
        out *= self._mask
        return out


@dataclass(frozen=True)
class TaskFrame:
    """What :meth:`TaskMap.rates` reuses from :meth:`TaskMap.evaluate` at one posture.

    Attributes:
        points: ``(4, 3)`` bottle and glass origins, then those plus their long axes ``a`` [m].
        proj: ``(2, 3)`` the axes' gaze coordinates ``p`` (right, up, forward).
        inv: ``(2,)`` ``1 / rho^2`` per object (0 where the axis is along the gaze: the angle is
            undefined there and its gradient is taken as 0).
        mix: ``(7, 12)`` ``J`` as a linear map of the stacked point Jacobians ``(4 * 3, n)``
            (rows 3: hold ``C R_gaze^T`` on ``A``).
        axis_jac: ``da/dq`` ``(2, 3, n)``, fixed joints' columns included.
    """

    points: np.ndarray
    proj: np.ndarray
    inv: np.ndarray
    mix: np.ndarray
    axis_jac: np.ndarray


@dataclass(frozen=True)
class Rollout:
    """One RMR rollout of a task trajectory.

    Attributes:
        q: ``(T + 1, n)`` joint angles [rad].
        x: ``(T + 1, m)`` task state reached, ``phi(q_t)``.
        jac: ``(T, m, n)`` task Jacobians at ``q_0 .. q_{T-1}``.
        pinv: ``(T, n, m)`` their weighted damped pseudo-inverses ``J^#``.
        limit_hessian: ``(T, n)`` diagonal Hessians of ``H`` at ``q_0 .. q_{T-1}``.
        solved: ``(T, m)`` ``(J W^-1 J^T + lambda I)^-1 (x_{t+1} - phi(q_t))``.
        frames: ``T`` :class:`TaskFrame` at ``q_0 .. q_{T-1}``.
        distances: ``T + 1`` :class:`Distances` (with gradients) of the pairs closer than the
            rollout's ``distmax``; empty if it was 0.
        clipped: Number of joint-angle clips to the joint ranges.
    """

    q: np.ndarray
    x: np.ndarray
    jac: np.ndarray
    pinv: np.ndarray
    limit_hessian: np.ndarray
    solved: np.ndarray
    frames: tuple[TaskFrame, ...]
    distances: tuple[Distances, ...]
    clipped: int


def _metric(kin: Kinematics, task: TaskMap) -> np.ndarray:
    return (kin.upper - kin.lower) * task.driven


def rollout(
    task: TaskMap,
    target: np.ndarray,
    q0: np.ndarray,
    config: ControlConfig,
    limits: JointLimitCost,
    distmax: float = 0.0,
) -> Rollout:
    """Tracks ``target`` ``(T + 1, m)`` (``target[0]`` unused) by RMR from ``q0`` ``(n,)``.

    Args:
        distmax: Compute the signed distances (and their gradients) of pairs closer than this
            [m] at every step; 0 for none.
    """
    kin = task.kin
    T = len(target) - 1
    n, m = kin.n, target.shape[1]
    winv = _metric(kin, task)
    q = np.empty((T + 1, n))
    x = np.empty((T + 1, m))
    jac = np.empty((T, m, n))
    pinv = np.empty((T, n, m))
    solved = np.empty((T, m))
    unclipped = np.empty((T, n))
    frames, distances = [], []
    q[0] = q0
    damped = config.damping * np.eye(m)
    rhs = np.empty((m, n + 1))
    angle_ref = target[:, [3, 5]]
    for t in range(T + 1):
        kin.update(q[t])
        x[t], J, frame = task.evaluate(angle_ref[t])
        if distmax > 0:
            distances.append(kin.distances(distmax, jacobian=True))
        if t == T:
            break
        JW = J * winv
        rhs[:, :n] = JW
        np.subtract(target[t + 1], x[t], out=rhs[:, n])
        sol = _solve_spd(JW @ J.T + damped, rhs)
        Jp, solved[t] = sol[:, :n].T, sol[:, n]
        step = JW.T @ solved[t]
        g = limits.gradient(q[t])
        if g.any():  # outside the free zone: the null-space joint-limit step
            g *= winv
            step -= config.nullspace_gain * (g - Jp @ (J @ g))
        np.add(q[t], step, out=unclipped[t])
        np.minimum(np.maximum(unclipped[t], kin.lower, out=q[t + 1]), kin.upper, out=q[t + 1])
        jac[t], pinv[t] = J, Jp
        frames.append(frame)
    hess = limits(q[:T])[2]
    clipped = int(np.count_nonzero(np.any(q[1:] != unclipped, axis=1)))
    return Rollout(q, x, jac, pinv, hess, solved, tuple(frames), tuple(distances), clipped)


def _solve_spd(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``matrix^-1 rhs`` for a symmetric positive definite ``matrix`` (LAPACK ``dposv``, a tenth
    of ``np.linalg.solve``'s overhead on these small systems); LU if Cholesky fails (NaN)."""
    _, sol, info = dposv(matrix, rhs)
    return sol if info == 0 else np.linalg.solve(matrix, rhs)


def backward(
    result: Rollout,
    task: TaskMap,
    config: ControlConfig,
    gq: np.ndarray,
    gx: np.ndarray,
) -> np.ndarray:
    r"""Total derivative w.r.t. the target trajectory by the adjoint recursion.

    ``lambda_T = gq_T``; ``lambda_t = gq_t + lambda_{t+1} dq_{t+1}/dq_t`` and
    ``dPhi/dx_{t+1} = gx_{t+1} + lambda_{t+1} J^#_t``, with

    .. math::
        \lambda \frac{\partial q_{t+1}}{\partial q_t} = \lambda (I - J^\# J)
        (I - \alpha W^{-1} H'') + u^T D_{\ell - z} J - p^T D_y J

    where ``u = M^-1 e``, ``p = (lambda J^#)^T``, ``l = W^-1 lambda^T``, ``y = J^# e``,
    ``z = W^-1 J^T p``, ``M = J W^-1 J^T + lambda I``, ``e = x_{t+1} - phi(q_t)``: the last two
    terms are ``lambda (dJ^#/dq) e``, using the symmetry of second derivatives,
    ``a^T (dJ/dq_i) b = [a^T D_b J]_i``, with ``D_b J`` the derivative of ``J`` along ``b``
    (:meth:`TaskMap.rates`, exact). Neglected: the derivative of the null-space projector times
    the joint-limit step (``alpha`` times a gradient that is zero inside the free zone).

    Args:
        gq: ``(T + 1, n)`` explicit gradients of the cost w.r.t. ``q_t``.
        gx: ``(T + 1, m)`` explicit gradients w.r.t. the target ``x_t``.

    Returns:
        ``(T + 1, m)`` gradient w.r.t. the target trajectory (row 0 is ``gx[0]``).
    """
    T = len(result.jac)
    kin = task.kin
    winv = _metric(kin, task)
    alpha = config.nullspace_gain
    dx = gx.copy()
    lam = gq[T].copy()
    for t in range(T - 1, -1, -1):
        Jp, J, u = result.pinv[t], result.jac[t], result.solved[t]
        p = lam @ Jp
        dx[t + 1] += p
        ln = lam - p @ J
        kin.update(result.q[t], held=False)
        curvature = task.curvature(
            u, winv * lam - winv * (J.T @ p), -p, winv * (J.T @ u), result.frames[t]
        )
        lam = gq[t] + ln - alpha * (ln * winv) * result.limit_hessian[t] + curvature
    return dx


def reach(
    task: TaskMap,
    goal: np.ndarray,
    q0: np.ndarray,
    config: ControlConfig,
    limits: JointLimitCost,
    steps: int = 200,
    rate: float = 0.2,
) -> np.ndarray:
    """Joint angles ``(n,)`` whose task state approaches ``goal`` ``(m,)``, by ``steps`` RMR
    steps from ``q0`` that each close ``rate`` of the remaining task error."""
    kin = task.kin
    target = np.empty((steps + 1, len(goal)))
    kin.update(q0)
    x0, _ = task(goal[[3, 5]])
    remaining = (1.0 - rate) ** np.arange(steps + 1)
    target[:] = goal + remaining[:, None] * (x0 - goal)
    return rollout(task, target, q0, config, limits).q[-1]
