"""The robot in the pouring scene: planning there, and playing a plan in physics.

:func:`planning_task` builds the kinematic planning model of a scene (no particles) and its
task map; :func:`reproduce` plans a learned model there; :func:`actions` are a plan's actions
at the env's step, and :func:`replay` drives ``PouringEnv``'s actuators with them in full
physics and measures the pour, or stops where the physics diverges.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from numbers import Real
from typing import cast

import gymnasium as gym
import numpy as np

from imitate.envs import assembly
from imitate.envs.pouring import PouringEnv
from imitate.errors import ImitateError
from imitate.learning import LearnedModel
from imitate.models import humanoid, objects
from imitate.motion import Plan, PlanConfig, plan_from_model
from imitate.motion.approach import approach_path
from imitate.motion.control import ControlConfig
from imitate.motion.kinematics import Kinematics
from imitate.motion.taskspace import TaskMap, task_space

GAZE_CAMERA = humanoid.LEFT_EYE
MIN_RANGE = 0.05  # [rad] the narrowest range narrowed_limits leaves a joint


def planning_task(
    config: assembly.SceneConfig | None = None,
    gaze: np.ndarray | None = None,
    control: ControlConfig | None = None,
    limit_margin: float = 0.0,
) -> TaskMap:
    """Task map on the scene's planning model (:func:`assembly.planning_model`; default:
    ``PouringEnv``'s scene), objects held by the robot, its kinematics updated to the rest pose.

    Args:
        config: The scene; ``None`` for ``PouringEnv``'s default.
        gaze: ``R_gaze`` ``(3, 3)``, right-handed, columns right, down, forward (e.g. the gaze
            stored with observed tracks); ``None`` for the rest pose's left-eye camera.
        control: Its ``fixed_joints`` get zero Jacobian columns; ``None`` for the default.
        limit_margin: Every planned joint's range narrowed by this much [rad] at each end, never
            past the rest pose (:func:`narrowed_limits`): the planner's clipping and its
            joint-limit cost see the narrowed ranges (its joint metric the full ones).

    Raises:
        ImitateError: a ``limit_margin`` :func:`narrowed_limits` refuses.
    """
    config, control = config or assembly.SceneConfig(), control or ControlConfig()
    model = assembly.planning_model(config)
    kin = Kinematics(model, humanoid.JOINTS, assembly.clearance_geoms(model))
    kin.lower, kin.upper = narrowed_limits(kin.lower, kin.upper, limit_margin)
    kin.update(humanoid.rest_pose())
    if gaze is None:
        _, R = kin.camera_pose(GAZE_CAMERA)
        # MuJoCo camera axes are right, up, backward: right, down, forward is x, -y, -z.
        gaze = np.column_stack((R[:, 0], -R[:, 1], -R[:, 2]))
    return TaskMap(kin, objects.BOTTLE, objects.GLASS, gaze, control.fixed_joints)


def narrowed_limits(
    lower: np.ndarray, upper: np.ndarray, margin: float
) -> tuple[np.ndarray, np.ndarray]:
    """The joint ranges ``lower``, ``upper`` ``(n,)`` [rad] of :data:`humanoid.JOINTS`
    narrowed by ``margin`` [rad] at each end, each end stopping at the rest pose
    (:func:`humanoid.rest_pose`): the rest posture stays within the range.

    Raises:
        ImitateError: a ``margin`` that is no finite number >= 0, or one that leaves a joint
            less than :data:`MIN_RANGE` of a wider range.
    """
    if isinstance(margin, bool) or not isinstance(margin, Real) or not 0 <= margin < np.inf:
        raise ImitateError(
            f"limit_margin={margin!r} not accepted: a finite angle >= 0 [rad]; 0 keeps the "
            "joints' full ranges"
        )
    rest = humanoid.rest_pose()
    low, high = np.minimum(lower + margin, rest), np.maximum(upper - margin, rest)
    closed = (high - low < MIN_RANGE) & (upper - lower >= MIN_RANGE)
    if np.any(closed):
        j = int(np.argmax(closed))
        raise ImitateError(
            f"limit_margin={margin!r} not accepted: it leaves joint {humanoid.JOINTS[j]!r} "
            f"{high[j] - low[j]:.3f} rad of its {upper[j] - lower[j]:.3f}, less than "
            f"{MIN_RANGE} rad; give a smaller margin"
        )
    return low, high


def reproduce(
    model: LearnedModel,
    *,
    gaze: np.ndarray | None = None,
    scene: assembly.SceneConfig | None = None,
    q0: np.ndarray | None = None,
    config: PlanConfig | None = None,
    **settings,
) -> Plan:
    """The robot's reproduction of ``model`` in ``scene``: :func:`plan_from_model` on
    :func:`planning_task`, nothing written.

    Args:
        model: A learned model (:func:`imitate.learn`'s) in the task space of ``gaze``.
        gaze: ``(3, 3)`` gaze frame the model's task space is expressed in (columns right,
            down, forward); ``None`` for the robot's left eye at the rest pose.
        scene: Obstacles and grasps; ``None`` for ``PouringEnv``'s default scene.
        q0: ``(n,)`` posture [rad] the movement starts from; ``None`` for the rest pose.
        config: The planner's settings; ``None`` for the defaults.
        **settings: Fields of :class:`PlanConfig` replaced in ``config`` (``collision_weight``,
            ``similarity``, ``max_iter``, ...).

    Raises:
        ImitateError: a setting :class:`PlanConfig` does not have, or a bad value.
    """
    config = (config or PlanConfig()).replace(**settings)
    q0 = humanoid.rest_pose() if q0 is None else q0
    return plan_from_model(planning_task(scene, gaze), model, q0=q0, config=config)


@dataclass(frozen=True)
class ReplayResult:
    """Outcome of :func:`replay`.

    Attributes:
        pour_fraction: Fraction of particles in the glass at the end.
        spilled: Particles in neither container at the end.
        min_distance: Smallest signed distance [m] over all steps between pairs that must not
            touch.
        task_error: ``(T + 1, m)`` task state in physics minus the plan's, at the plan's times
            (fewer rows if the replay stopped early).
        is_success: The pour fraction is a pour (:func:`imitate.envs.outcome.poured`) and the
            physics did not diverge.
        diverged_at: Time [s] into the replay at which the physics diverged (the replay stopped
            there), None if it did not.
    """

    pour_fraction: float
    spilled: int
    min_distance: float
    task_error: np.ndarray
    is_success: bool
    diverged_at: float | None = None


def actions(
    plan: Plan, env: gym.Env | PouringEnv, *, approach: float = 1.0, settle: float = 1.5
) -> np.ndarray:
    """The env's actions that play ``plan``, one per env step: ``(N, 18)`` joint targets
    [rad] from the env's joint positions now (call it after ``env.reset``) to the plan's start
    in ``approach`` [s] along the plan's approach path (cosine blend), the plan interpolated at
    the env's step ``env.dt``, then ``settle`` [s] holding the last posture; each target led by
    its speed times ``env.servo_lag`` plus half a step (velocity feed-forward: the position
    servos trail a moving target).

    Args:
        plan: The plan (``Plan.times`` at the planner's step, 0.08 s by default).
        env: ``PouringEnv``, or ``gym.make("imitate:imitate/Pouring-v0")`` (its wrappers are
            looked through).
        approach: Time [s] from the reset posture to the plan's start.
        settle: Time [s] holding the last posture.
    """
    env = cast(PouringEnv, env.unwrapped)
    dt = env.dt
    n_approach = int(round(approach / dt))
    blend = 0.5 - 0.5 * np.cos(np.pi * np.arange(1, n_approach + 1) / n_approach)
    waypoints = [
        *approach_path(env.joint_positions(), plan.q_start, plan.approach_bend, blend),
        *_resample(plan.times - plan.times[0], plan.q, _play_times(plan, dt)),
        *[plan.q[-1]] * int(round(settle / dt)),
    ]
    targets = np.array(waypoints)
    return targets + (env.servo_lag + dt / 2) * np.gradient(targets, dt, axis=0)


def replay(
    plan: Plan,
    env: PouringEnv,
    *,
    seed: int = 0,
    approach: float = 1.0,
    settle: float = 1.5,
    options: dict | None = None,
    on_step: Callable[[PouringEnv], None] | None = None,
    gaze: np.ndarray | None = None,
) -> ReplayResult:
    """Drives ``env`` along ``plan`` in physics (its :func:`actions` after a reset from
    ``seed`` with ``options``) and measures the pour, the clearance and the task error.
    ``on_step(env)``, if given, is called after the reset and after every step (to record
    states for a video, say). The task error is measured in ``gaze``, which should be the
    plan's (``None``: :func:`planning_task`'s default).

    Where the physics diverges (``info["diverged"]`` of a step), the replay stops and says when
    (``diverged_at``), with the pour and the clearance measured so far.
    """
    env.reset(seed=seed, options=options)
    dt = env.dt
    targets = actions(plan, env, approach=approach, settle=settle)
    n_approach = int(round(approach / dt))
    t_play = _play_times(plan, dt)
    task = planning_task(env.config, gaze)
    min_distance = np.inf
    reached = []
    info = {}
    diverged_at = None
    if on_step is not None:
        on_step(env)
    for k, target in enumerate(targets):
        _, _, _, _, info = env.step(target)
        if info["diverged"]:
            diverged_at = (k + 1) * dt
            break
        if on_step is not None:
            on_step(env)
        min_distance = min(min_distance, info["min_distance"])
        if n_approach <= k < n_approach + len(t_play):
            reached.append(_task_state(env, task, plan, (k - n_approach) * dt))
    x = np.reshape(reached, (len(reached), plan.x.shape[1]))
    ref = _resample(plan.times - plan.times[0], plan.x, t_play)
    return ReplayResult(
        pour_fraction=float(info["pour_fraction"]),
        spilled=int(info["spilled"]),
        min_distance=float(min_distance),
        task_error=x - ref[: len(x)],
        is_success=bool(info["is_success"]) and diverged_at is None,
        diverged_at=diverged_at,
    )


def _play_times(plan: Plan, dt: float) -> np.ndarray:
    """Times [s] from the plan's start of its env steps ``dt`` apart."""
    return np.arange(0.0, plan.times[-1] - plan.times[0] + 1e-9, dt)


def _resample(times: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Linear interpolation of ``values`` ``(T, k)`` at ``times`` onto ``at``."""
    return np.column_stack([np.interp(at, times, values[:, i]) for i in range(values.shape[1])])


def _task_state(env: PouringEnv, task: TaskMap, plan: Plan, t: float) -> np.ndarray:
    """Task state of the objects' physical poses (not the hands'), eq. 1."""
    d = env.data
    pb, pg = d.body(objects.BOTTLE).xpos, d.body(objects.GLASS).xpos
    ab = d.body(objects.BOTTLE).xmat.reshape(3, 3)[:, 2]
    ag = d.body(objects.GLASS).xmat.reshape(3, 3)[:, 2]
    x = task_space(pb[None], ab[None], pg[None], ag[None], task.gaze)[0]
    ref = np.array([np.interp(t, plan.times - plan.times[0], plan.x[:, i]) for i in (3, 5)])
    x[[3, 5]] += 2 * np.pi * np.round((ref - x[[3, 5]]) / (2 * np.pi))
    return x


__all__ = ["ReplayResult", "narrowed_limits", "planning_task", "replay"]
