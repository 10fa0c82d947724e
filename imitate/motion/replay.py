"""Planning set-up for the robot in the pouring scene, and replay.

:func:`planning_task` builds the kinematic planning model of a scene (no particles) and its
task map; :func:`replay` drives ``PouringEnv``'s actuators along a plan in full
physics and measures the pour, or stops where the physics diverges.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from imitate.envs import assembly
from imitate.envs.pouring import PouringEnv
from imitate.models import humanoid, objects
from imitate.motion import Plan
from imitate.motion.approach import approach_path
from imitate.motion.control import ControlConfig
from imitate.motion.kinematics import Kinematics
from imitate.motion.taskspace import TaskMap, task_space

GAZE_CAMERA = humanoid.LEFT_EYE


def planning_task(
    config: assembly.SceneConfig | None = None,
    gaze: np.ndarray | None = None,
    control: ControlConfig | None = None,
) -> TaskMap:
    """Task map on the scene's planning model (:func:`assembly.planning_model`; default:
    ``PouringEnv``'s scene), objects held by the robot, its kinematics updated to the rest pose.

    Args:
        config: The scene; ``None`` for ``PouringEnv``'s default.
        gaze: ``R_gaze`` ``(3, 3)``, right-handed, columns right, down, forward (e.g. the gaze
            stored with observed tracks); ``None`` for the rest pose's left-eye camera.
        control: Its ``fixed_joints`` get zero Jacobian columns; ``None`` for the default.
    """
    config, control = config or assembly.SceneConfig(), control or ControlConfig()
    model = assembly.planning_model(config)
    kin = Kinematics(model, humanoid.JOINTS, assembly.clearance_geoms(model))
    kin.update(humanoid.rest_pose())
    if gaze is None:
        _, R = kin.camera_pose(GAZE_CAMERA)
        # MuJoCo camera axes are right, up, backward: right, down, forward is x, -y, -z.
        gaze = np.column_stack((R[:, 0], -R[:, 1], -R[:, 2]))
    return TaskMap(kin, objects.BOTTLE, objects.GLASS, gaze, control.fixed_joints)


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
    """Drives ``env`` along ``plan`` in physics: from the reset pose to the plan's start in
    ``approach`` [s] along the plan's approach path (cosine blend), the plan interpolated at
    the env's control rate, then
    ``settle`` [s] holding the last posture; each target led by its speed times
    ``env.servo_lag`` plus half a step (velocity feed-forward). ``on_step(env)``, if given,
    is called after the reset and after every step (to record states for a video, say). The
    task error is measured in ``gaze``, which should be the plan's (``None``:
    :func:`planning_task`'s default).

    Where the physics diverges (``info["diverged"]`` of a step), the replay stops and says when
    (``diverged_at``), with the pour and the clearance measured so far.
    """
    env.reset(seed=seed, options=options)
    dt = env.dt
    q_reset = env.joint_positions()
    waypoints: list[np.ndarray] = []
    n_approach = int(round(approach / dt))
    blend = 0.5 - 0.5 * np.cos(np.pi * np.arange(1, n_approach + 1) / n_approach)
    waypoints.extend(approach_path(q_reset, plan.q_start, plan.approach_bend, blend))
    t_play = np.arange(0.0, plan.times[-1] - plan.times[0] + 1e-9, dt)
    play = _resample(plan.times - plan.times[0], plan.q, t_play)
    waypoints.extend(play)
    waypoints.extend([plan.q[-1]] * int(round(settle / dt)))
    # Velocity feed-forward: each step holds its target (half a step behind on average) and the
    # servos trail a moving target by servo_lag; both are led by the target's speed.
    targets = np.array(waypoints)
    targets += (env.servo_lag + dt / 2) * np.gradient(targets, dt, axis=0)
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
        if n_approach <= k < n_approach + len(play):
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


__all__ = ["ReplayResult", "planning_task", "replay"]
