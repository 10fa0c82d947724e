"""The robot in a task's scene: planning there, and playing a plan in physics.

:func:`planning_task` builds the kinematic planning model of a scene (hulls only) and its task
map; :func:`reproduce` plans a learned model there; :func:`actions` are a plan's actions at the
env's step, and :func:`replay` drives a task env's actuators with them in full physics, or
stops where the physics diverges; :func:`measure` replays a plan and records what the task
measures (the one replay-and-record of the replay stage and the evaluation).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from numbers import Real
from typing import Any, cast

import gymnasium as gym
import numpy as np

from imitate.envs import assembly
from imitate.envs.bimanual import BimanualEnv
from imitate.envs.task import Task
from imitate.errors import ImitateError
from imitate.learning import LearnedModel
from imitate.learning.tpgmm import FrameModel
from imitate.models import humanoid
from imitate.motion import Plan, PlanConfig, plan_from_model
from imitate.motion.approach import approach_path
from imitate.motion.control import ControlConfig
from imitate.motion.kinematics import Kinematics
from imitate.motion.taskspace import TaskMap
from imitate.taskspace import EQ1, TaskSpace, gaze_of_camera

GAZE_CAMERA = humanoid.LEFT_EYE
MIN_RANGE = 0.05  # [rad] the narrowest range narrowed_limits leaves a joint


def planning_task(
    config: assembly.SceneConfig | None = None,
    gaze: np.ndarray | None = None,
    control: ControlConfig | None = None,
    limit_margin: float = 0.0,
) -> TaskMap:
    """Task map on the scene's planning model (:func:`assembly.planning_model`), objects held
    by the robot, its kinematics updated to the rest pose.

    Args:
        config: The scene; ``None`` for ``SceneConfig()``'s.
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
        gaze = gaze_of_camera(kin.camera_pose(GAZE_CAMERA)[1], mujoco=True)
    tool, target = config.objects
    return TaskMap(kin, tool, target, gaze, control.fixed_joints, config.space)


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
    model: LearnedModel | FrameModel,
    *,
    gaze: np.ndarray | None = None,
    scene: assembly.SceneConfig | None = None,
    q0: np.ndarray | None = None,
    config: PlanConfig | None = None,
    critical: Callable[[np.ndarray], np.ndarray] | None = None,
    **settings,
) -> Plan:
    """The robot's reproduction of ``model`` in ``scene``: :func:`plan_from_model` on
    :func:`planning_task`, nothing written.

    Args:
        model: A learned model (:func:`imitate.learn`'s) in the task space of ``gaze``, or one
            in TP-GMM's frames (reproduced at ``scene``'s places).
        gaze: ``(3, 3)`` gaze frame the model's task space is expressed in (columns right,
            down, forward); ``None`` for the robot's left eye at the rest pose.
        scene: Objects, obstacles and grasps; ``None`` for ``SceneConfig()``.
        q0: ``(n,)`` posture [rad] the movement starts from; ``None`` for the rest pose.
        config: The planner's settings; ``None`` for the defaults.
        critical: The task's critical phase (``Task.critical``), for the oracle weighting.
        **settings: Fields of :class:`PlanConfig` replaced in ``config`` (``collision_weight``,
            ``similarity``, ``max_iter``, ...).

    Raises:
        ImitateError: a setting :class:`PlanConfig` does not have, or a bad value.
    """
    config = (config or PlanConfig()).replace(**settings)
    q0 = humanoid.rest_pose() if q0 is None else q0
    return plan_from_model(
        planning_task(scene, gaze), model, q0=q0, config=config, critical=critical
    )


@dataclass(frozen=True)
class ReplayResult:
    """Outcome of :func:`replay`.

    Attributes:
        info: The env's ``info`` of the last step (the task's measures at the end).
        min_distance: Smallest signed distance [m] over all steps between pairs that must not
            touch.
        task_error: ``(T + 1, m)`` task state in physics minus the plan's, at the plan's times
            (fewer rows if the replay stopped early).
        diverged_at: Time [s] into the replay at which the physics diverged (the replay stopped
            there), None if it did not.
    """

    info: Mapping[str, Any]
    min_distance: float
    task_error: np.ndarray
    diverged_at: float | None = None


def actions(
    plan: Plan, env: gym.Env | BimanualEnv, *, approach: float = 1.0, settle: float = 1.5
) -> np.ndarray:
    """The env's actions that play ``plan``, one per env step: ``(N, 18)`` joint targets
    [rad] from the env's joint positions now (call it after ``env.reset``) to the plan's start
    in ``approach`` [s] along the plan's approach path (cosine blend), the plan interpolated at
    the env's step ``env.dt``, then ``settle`` [s] holding the last posture; each target led by
    its speed times ``env.servo_lag`` plus half a step (velocity feed-forward: the position
    servos trail a moving target).

    Args:
        plan: The plan (``Plan.times`` at the planner's step, 0.08 s by default).
        env: A task's env (``BimanualEnv``), or ``gym.make`` of its id (its wrappers are looked
            through).
        approach: Time [s] from the reset posture to the plan's start.
        settle: Time [s] holding the last posture.
    """
    env = cast(BimanualEnv, env.unwrapped)
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
    env: BimanualEnv,
    *,
    seed: int = 0,
    approach: float = 1.0,
    settle: float = 1.5,
    options: dict | None = None,
    on_step: Callable[[BimanualEnv], None] | None = None,
    gaze: np.ndarray | None = None,
    space: TaskSpace = EQ1,
) -> ReplayResult:
    """Drives ``env`` along ``plan`` in physics (its :func:`actions` after a reset from
    ``seed`` with ``options``) and measures the clearance and the task error.
    ``on_step(env)``, if given, is called after the reset and after every step (to record
    states for a video, say). The task error is measured in the plan's task ``space`` and
    ``gaze``, which should be the plan's (``None``: :func:`planning_task`'s default).

    Where the physics diverges (``info["diverged"]`` of a step), the replay stops and says when
    (``diverged_at``), with the clearance measured so far.
    """
    env.reset(seed=seed, options=options)
    dt = env.dt
    targets = actions(plan, env, approach=approach, settle=settle)
    n_approach = int(round(approach / dt))
    t_play = _play_times(plan, dt)
    if gaze is None:
        gaze = planning_task(env.config).gaze
    tool, target = (env.data.body(obj) for obj in env.objects)
    min_distance = np.inf
    poses = []  # the objects' positions and long axes (4, 3) at the plan's times
    info = {}
    diverged_at = None
    if on_step is not None:
        on_step(env)
    for k, action in enumerate(targets):
        _, _, _, _, info = env.step(action)
        if info["diverged"]:
            diverged_at = (k + 1) * dt
            break
        if on_step is not None:
            on_step(env)
        min_distance = min(min_distance, info["min_distance"])
        if n_approach <= k < n_approach + len(t_play):
            poses.append(np.array((tool.xpos, tool.xmat[2::3], target.xpos, target.xmat[2::3])))
    ref = _resample(plan.times - plan.times[0], plan.x, t_play)
    places = {name: env.data.body(name).xpos.copy() for name in space.places}
    states = _task_states(space, np.reshape(poses, (-1, 4, 3)), places, ref, gaze)
    return ReplayResult(
        info=dict(info),
        min_distance=float(min_distance),
        task_error=states - ref[: len(poses)],
        diverged_at=diverged_at,
    )


def measure(
    task: Task,
    plan: Plan,
    env: BimanualEnv,
    *,
    seed: int,
    gaze: np.ndarray,
    options: Mapping[str, Any],
    approach: float = 1.0,
    on_step: Callable[[BimanualEnv], None] | None = None,
) -> tuple[ReplayResult, dict[str, Any], dict[str, Any]]:
    """``plan`` replayed in ``env`` (a fresh env of ``task``'s, closed afterwards) from
    ``seed`` with the task's settings ``options``, watched by the task's watcher.

    Returns:
        The :class:`ReplayResult`; the replay's record: the task's measures at the end,
        ``min_distance_m`` [m] and ``diverged``; and the watcher's summary.
    """
    watcher = task.watcher()

    def step(env: BimanualEnv) -> None:
        watcher(env)
        if on_step is not None:
            on_step(env)

    result = replay(plan, env, seed=seed, approach=approach,
                    options=task.reset_options(options), on_step=step, gaze=gaze,
                    space=task.space)
    env.close()
    record = {**task.record(result.info), "min_distance_m": result.min_distance,
              "diverged": result.diverged_at is not None}
    return result, record, watcher.summary()


def _play_times(plan: Plan, dt: float) -> np.ndarray:
    """Times [s] from the plan's start of its env steps ``dt`` apart."""
    return np.arange(0.0, plan.times[-1] - plan.times[0] + 1e-9, dt)


def _resample(times: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Linear interpolation of ``values`` ``(T, k)`` at ``times`` onto ``at``."""
    return np.column_stack([np.interp(at, times, values[:, i]) for i in range(values.shape[1])])


def _task_states(
    space: TaskSpace, poses: np.ndarray, places: Mapping[str, np.ndarray], ref: np.ndarray,
    gaze: np.ndarray,
) -> np.ndarray:
    """``space`` of the objects' physical poses (not the hands'): ``poses`` ``(n, 4, 3)`` the
    tool's position and long axis, then the target's, per step [m], ``places`` the places'
    positions ``(3,)`` [m]; each angle taken within half a turn of the plan's ``ref`` ``(>= n,
    m)`` at the same step."""
    if len(poses) == 0:
        return np.zeros((0, ref.shape[1]))
    p_tool, a_tool, p_target, a_target = poses.transpose(1, 0, 2)
    tracks = {"tool": (p_tool, a_tool), "target": (p_target, a_target),
              **{name: (np.broadcast_to(p, p_tool.shape), None) for name, p in places.items()}}
    x = space(tracks, gaze)
    cols = space.angles
    x[:, cols] += 2 * np.pi * np.round((ref[: len(x), cols] - x[:, cols]) / (2 * np.pi))
    return x


__all__ = ["ReplayResult", "measure", "narrowed_limits", "planning_task", "replay"]
