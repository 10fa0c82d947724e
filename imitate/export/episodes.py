"""A run's episodes: the robot's reproduction replayed in its task's env, and the teacher's
demonstrations.

The robot's episode is a real sequence of env transitions: :func:`imitate.motion.replay.replay`
drives the run's task's env along the run's plan exactly as the replay stage does (same
settings, seed and grasps) while :class:`Recorder` keeps what every ``reset`` and ``step``
returned.

The teacher's episodes are its segmented demonstrations at camera rate. The teacher has no
actions to record, so an action is the **next frame's true object poses** (the state it moves
the objects to): every format here needs one action per step, and this is the usual choice for
learning from observed states.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any, cast

import gymnasium as gym
import mujoco
import numpy as np

from imitate.demos.segment import place_positions, task_demo
from imitate.envs.assembly import Obstacle
from imitate.envs.bimanual import BimanualEnv
from imitate.envs.observation import EYES, ObservationConfig, frames, session
from imitate.envs.task import Task, get_task
from imitate.envs.teacher_motion import script_demonstrations
from imitate.models import humanoid
from imitate.motion import Plan
from imitate.motion.replay import replay
from imitate.run import Run
from imitate.stages.progress import bar

__all__ = [
    "Episode", "Recorder", "image_kwargs", "obstacle_vector", "recorded", "robot_episode",
    "teacher_episodes",
]

POSE = ("x", "y", "z", "qw", "qx", "qy", "qz")  # an object frame: position [m], quaternion wxyz
# An obstacle or fixture as an observation: there (1) or not (0, all zeros), a box (1) or an
# upright cylinder (0), its centre [m] and half extents [m] (a cylinder's: radius, radius, half
# height); an evaluated variation's places for them, its obstacle and its fixtures.
OBSTACLE = ("present", "box", "x", "y", "z", "half_x", "half_y", "half_z")
PLACES = ("obstacle", "shelf", "plate")
# What ``Episode.states`` hold: MuJoCo's whole integration state (mj_getState's spec), enough to
# continue the physics bit for bit from any step (mj_setState, then the step's action).
STATE_SPEC = mujoco.mjtState.mjSTATE_INTEGRATION


@dataclass(frozen=True, eq=False)
class Episode:
    """One episode of ``n`` steps.

    Attributes:
        observations: Name -> ``(n + 1, ...)``: the reset's observation, then one per step;
            vectors ``(n + 1, k)`` float64, images ``(n + 1, height, width, 3)`` uint8 (keyed
            by camera, see :attr:`images`).
        actions: ``(n, k)`` float64.
        rewards: ``(n,)``.
        terminations, truncations: ``(n,)`` bool.
        infos: Name -> ``(n + 1,)``, the reset's first.
        names: Name of each vector observation's and the action's components.
        dt: Time between observations [s].
        env: The Gymnasium spec that recreates the env (``None``: not from an env).
        seed, options: The reset's seed and options (``None``: no reset).
        metadata: What the episode is beyond its env (``None``: nothing more); JSON-ready.
        states: ``(n + 1, k)`` MuJoCo states (:data:`STATE_SPEC`) at each observation
            (``None``: not from physics).
        instruction: What the robot is asked to do (its task's ``instruction``).
        environment: The vector observations that are the environment's state, not the
            robot's: the objects' frames (an evaluated variation's obstacle and fixtures too).
    """

    observations: dict[str, np.ndarray]
    actions: np.ndarray
    rewards: np.ndarray
    terminations: np.ndarray
    truncations: np.ndarray
    infos: dict[str, np.ndarray]
    names: dict[str, tuple[str, ...]]
    dt: float
    env: gym.envs.registration.EnvSpec | None = None
    seed: int | None = None
    options: dict | None = None
    metadata: dict | None = None
    states: np.ndarray | None = None
    instruction: str = ""
    environment: tuple[str, ...] = ()

    def __len__(self) -> int:
        return len(self.actions)

    @property
    def images(self) -> tuple[str, ...]:
        """The observations that are images (uint8 ``(n + 1, height, width, 3)``)."""
        return tuple(k for k, v in self.observations.items() if v.dtype == np.uint8)


class Recorder(gym.Wrapper):
    """Keeps what every ``reset`` and ``step`` of the wrapped task env returned.

    :func:`imitate.motion.replay.replay` drives it as it would the env: the env's own attributes
    (``dt``, ``data``, ``config``, ``joint_positions``) are read through.
    """

    def __init__(self, env: BimanualEnv):
        super().__init__(env)
        self.seed, self.options = None, None
        self.observations: list[np.ndarray | dict[str, Any]] = []
        self.infos: list[dict[str, Any]] = []
        self.actions: list[np.ndarray] = []
        self.steps: list[tuple[float, bool, bool]] = []  # reward, terminated, truncated
        self.states: list[np.ndarray] = []

    def reset(self, *, seed=None, options=None):
        obs, info = self.env.reset(seed=seed, options=options)
        self.seed, self.options = seed, options
        self.observations, self.infos, self.actions, self.steps = [obs], [info], [], []
        self.states = [self._state()]
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        self.actions.append(np.array(action, dtype=float))
        self.observations.append(obs)
        self.infos.append(info)
        self.steps.append((reward, terminated, truncated))
        self.states.append(self._state())
        return obs, reward, terminated, truncated, info

    def _state(self) -> np.ndarray:
        """The env's MuJoCo state now, ``(k,)`` (:data:`STATE_SPEC`)."""
        env = cast(BimanualEnv, self.env.unwrapped)
        state = np.empty(mujoco.mj_stateSize(env.model, STATE_SPEC))
        mujoco.mj_getState(env.model, env.data, state, STATE_SPEC)
        return state

    def __getattr__(self, name: str):
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self.env.unwrapped, name)


def robot_episode(run: Run, images: bool = False) -> Episode:
    """The run's plan replayed in its task's env as the replay stage does, recorded.

    The env gets the run's settings as its kwargs (with ``images``, ``obs_type="state_pixels"`` at
    the run's camera size); the episode's spec is the task's env id's with these kwargs and the
    episode's length as its time limit, so its last step is truncated, as that ``TimeLimit``
    truncates it.

    Args:
        run: The run; needs its config, ``model.npz`` (the gaze) and ``plan.npz``.
        images: Also record the env's camera images (the env's default ``cameras``, the
            workspace camera) at every step.
    """
    config = run.config
    task = run.task
    scene = config.scene(task=task)
    kwargs: dict[str, Any] = {**task.env_kwargs(scene), **image_kwargs(run, images)}
    return recorded(
        task, run.plan, task.env(**kwargs), kwargs, config.seed, task.scene_reset(scene), run.gaze
    )


def image_kwargs(run: Run, images: bool) -> dict[str, Any]:
    """A task env's kwargs for its camera images at the run's size, if ``images``; the
    cameras and the teacher's absence named, so that a dataset's env spec keeps them."""
    if not images:
        return {}
    return {
        "obs_type": "state_pixels", "width": run.config.width, "height": run.config.height,
        "cameras": [humanoid.WORKSPACE], "teacher": False,
    }


def recorded(
    task: Task,
    plan: Plan,
    env: BimanualEnv,
    kwargs: dict[str, Any],
    seed: int,
    options: dict,
    gaze: np.ndarray,
) -> Episode:
    """``plan`` replayed in ``env`` (``task``'s, made with ``kwargs``, closed here) from
    ``seed`` and the reset ``options``, recorded as an :class:`Episode`; its last step
    truncated (see :func:`robot_episode`)."""
    recorder = Recorder(env)
    try:
        # The Recorder stands in for the env it wraps (its attributes are read through).
        with bar(desc=f"{task.name} episode", unit="step") as progress:  # images take minutes
            replay(plan, cast(BimanualEnv, recorder), seed=seed, options=options, gaze=gaze,
                   space=task.space, on_step=lambda _: progress.update())
    finally:
        recorder.close()
    rewards, terminated, truncated = (np.array(v) for v in zip(*recorder.steps, strict=True))
    truncated[-1] = True  # the spec's TimeLimit ends the episode here
    structure = recorder.observation_structure
    states = np.array(
        [o if isinstance(o, np.ndarray) else o["state"] for o in recorder.observations]
    )
    bounds = np.cumsum([0, *structure.values()])
    observations = {
        name: states[:, start:stop]
        for name, start, stop in zip(structure, bounds[:-1], bounds[1:], strict=True)
    }
    if kwargs.get("obs_type") == "state_pixels":
        observations.update({
            camera: np.array([o["pixels"][camera] for o in recorder.observations])
            for camera in recorder.cameras
        })
    names = {
        "qpos": humanoid.JOINTS, "qvel": humanoid.JOINTS,
        **{obj: POSE for obj in task.objects}, "action": humanoid.JOINTS,
    }
    spec = dataclasses.replace(
        gym.spec(task.env_id), kwargs=kwargs, max_episode_steps=len(recorder.actions)
    )
    return Episode(
        observations=observations, actions=np.array(recorder.actions), rewards=rewards,
        terminations=terminated, truncations=truncated, infos=_stacked(recorder.infos),
        names=names, dt=recorder.dt, env=spec, seed=recorder.seed, options=recorder.options,
        states=np.array(recorder.states), instruction=task.words.instruction,
        environment=task.objects,
    )


def teacher_episodes(run: Run, images: bool = False) -> Iterator[Episode]:
    """The teacher's demonstrations as the robot cut them, one episode each, in time order.

    Observations: ``task`` ``(n + 1, m)``, the task's space of the tracked objects as
    learning takes it (labelled by the task's ``dims``); the tool and the target by name
    ``(n + 1, 7)``, the true object frames (position [m], quaternion wxyz); with ``images``,
    both eyes' images as the robot saw them. Actions: ``(n, 14)`` the next frame's true tool
    and target, named as those observations are (``<tool>.x``, ..., ``<target>.qz``). Rewards
    are 0 (none is defined for the teacher); the last step terminates (the demonstration is
    complete). Infos: ``time``, the session time [s] of each frame.
    """
    config = run.config
    task = get_task(config.task)
    objects = task.objects
    motion = script_demonstrations(config.teacher())
    demos = run.demos
    watching = None
    if images:
        watching = session(ObservationConfig(
            teacher=config.teacher(), fps=config.fps, width=config.width, height=config.height,
        ))
    names = {
        "task": task.dims, **{obj: POSE for obj in objects},
        "action": tuple(f"{obj}.{c}" for obj in objects for c in POSE),
    }
    places = place_positions(demos.segments, demos.objects)
    for demo, placed in zip(demos.segments, places, strict=True):
        poses = motion.poses(demo.times)
        true = {obj: np.hstack(poses[obj]) for obj in objects}
        states = task_demo(
            demo, demos.objects, demos.gaze, task.space, placed, smoothing=config.smoothing,
            rate=config.fps,
        )
        observations = {"task": states, **true}
        if watching is not None:
            pairs = list(frames(dataclasses.replace(watching, times=demo.times)))
            observations.update({eye: np.array(eye_images) for eye, eye_images in zip(
                EYES, zip(*pairs, strict=True), strict=True
            )})
        n = len(demo.times) - 1
        yield Episode(
            observations=observations,
            actions=np.hstack([true[obj] for obj in objects])[1:],
            rewards=np.zeros(n), terminations=np.arange(n) == n - 1,
            truncations=np.zeros(n, dtype=bool), infos={"time": demo.times}, names=names,
            dt=1.0 / config.fps, instruction=task.words.instruction, environment=objects,
        )


def obstacle_vector(obstacle: Obstacle | None) -> np.ndarray:
    """``obstacle`` (or a fixture) as an observation ``(8,)``, see :data:`OBSTACLE`; ``None``:
    zeros."""
    if obstacle is None:
        return np.zeros(len(OBSTACLE))
    size = obstacle.size if obstacle.shape == "box" else (obstacle.size[0], *obstacle.size)
    return np.array([1.0, float(obstacle.shape == "box"), *obstacle.pos, *size])


def _stacked(infos: list[dict]) -> dict[str, np.ndarray]:
    """Per-step ``infos`` as arrays ``(n + 1,)`` per key; a key the reset's info lacks (the
    reward terms) is 0 there."""
    return {key: np.array([info.get(key, 0) for info in infos]) for key in infos[-1]}
