"""``BimanualEnv``: the humanoid holds a task's tool in its right hand and its target in its
left, at a table; each task's env (``PouringEnv``, ``InsertingEnv``) adds what it measures.

The robot, the objects' welds, the obstacles, the observation spaces (state and the head
cameras' pixels), the divergence check and the clearance are the same for every task, and
documented on each task env's page. A task env sets ``objects`` (tool, target), may add to its
scene (:meth:`scene_config`: contents, places) and fills in :meth:`_task_reset`,
:meth:`_task_info` and :meth:`_task_reward`.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping
from numbers import Real
from typing import Any, ClassVar

import gymnasium as gym
import mujoco
import numpy as np

from imitate.envs import assembly, tasks
from imitate.envs.collision import CollisionPairs, signed_distances
from imitate.envs.mannequin import pose_arm, shoulder_position
from imitate.envs.rendering import make_renderer
from imitate.errors import ImitateError
from imitate.models import humanoid, shapes
from imitate.models import scene as scene_names
from imitate.models import teacher as teacher_names

OBS_TYPES = ("state", "pixels", "pixels_agent_pos", "state_pixels")
# How images are rendered: "fast" for learning from pixels (no shadows, reflections or
# multisampling, spheres and capsules of fewer facets: on a CPU, Mesa's llvmpipe, a pour's
# 96x96 pixel observations step 8x faster, scripts/bench/bench_env_rates.py), "full" for people.
RENDER_QUALITIES = ("fast", "full")
FAST_FACETS = (12, 8)  # slices and stacks of a sphere or capsule in "fast" images (MuJoCo's 28, 16)
# MuJoCo's warnings that it found the state diverged (it then resets it).
DIVERGENCE = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
)
# How fast [rad/s] the joint targets may move by default: a step's action is followed at most
# this far (``max_target_speed * dt``). Planned movements stay well below it, so their replays
# are unchanged (tests/test_env.py); uniform random targets, followed at once, slammed the arms
# through the body and diverged the physics in 20 of 20 episodes of Inserting-v0 and 10 of 20 of
# Pouring-v0 (scripts/experiments/random_actions.py).
MAX_TARGET_SPEED = 10.0
# How far [rad] an observed joint angle may lie past its limit (MuJoCo's limits are soft):
# about twice the furthest 100 episodes of uniform random actions per task pushed one (0.236
# rad, MarkedPouring-v0; scripts/experiments/random_actions.py); the observation is clipped to
# it, so it lies in its space.
JOINT_SLACK = 0.5
# How far [m] below its shoulder the teacher's hand hangs at rest (arms down, hands by the hips).
TEACHER_HAND_DROP = 0.53


class BimanualEnv(gym.Env):
    """A task's two objects in the robot's hands, in full physics (see the module docstring).

    Attributes:
        task: The task's name (its default grasps), set by the task's env.
        objects: The tool and the target, set by the task's env.
        contact: How the tool meets the target (``SceneConfig.contact``).
        measures: What the task measures of an episode: keys of ``info`` at its last step, with
            unit (``"-"``: a count) and meaning; set by the task's env.
    """

    task: str
    objects: tuple[str, str]
    contact: str = "apart"
    measures: ClassVar[Mapping[str, tuple[str, str]]] = {}

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}  # 1 / dt at the default frame_skip

    def __init__(
        self,
        render_mode: str | None = None,
        obs_type: str = "state",
        camera: str = scene_names.OVERVIEW,
        cameras: tuple[str, ...] = (humanoid.WORKSPACE,),
        width: int = 640,
        height: int = 480,
        obstacles: tuple[assembly.Obstacle | dict, ...] = (),
        teacher: bool = False,
        frame_skip: int = 10,
        reset_noise_scale: float = 0.01,
        collision_weight: float = 1.0,
        render_quality: str = "fast",
        max_target_speed: float = MAX_TARGET_SPEED,
        **scene: Any,
    ):
        _check_choice("render_mode", render_mode, (None, *self.metadata["render_modes"]))
        _check_choice("render_quality", render_quality, RENDER_QUALITIES)
        _check_choice("obs_type", obs_type, OBS_TYPES)
        _check_choice("camera", camera, scene_names.CAMERAS)
        cameras = tuple(cameras) if isinstance(cameras, list | tuple) else (cameras,)
        if not cameras or len(set(cameras)) < len(cameras) or set(cameras) - {*humanoid.CAMERAS}:
            raise ImitateError(
                f"cameras={cameras!r} not accepted: distinct names of {list(humanoid.CAMERAS)}"
            )
        for name, value in (("width", width), ("height", height), ("frame_skip", frame_skip)):
            if not isinstance(value, int | np.integer) or value <= 0:
                raise ImitateError(f"{name}={value!r} not accepted: a positive integer")
        check_weight("reset_noise_scale", reset_noise_scale)
        check_weight("collision_weight", collision_weight)
        speed_ok = isinstance(max_target_speed, Real) and not isinstance(max_target_speed, bool)
        if not (speed_ok and max_target_speed > 0):
            raise ImitateError(
                f"max_target_speed={max_target_speed!r} not accepted: a speed > 0 [rad/s] "
                "(math.inf: the targets jump to each action)"
            )
        self.max_target_speed = float(max_target_speed)
        self.render_mode, self.obs_type, self.camera = render_mode, obs_type, camera
        self.cameras = cameras
        self.width, self.height = width, height
        self.render_quality = render_quality
        self.frame_skip = frame_skip
        self._reset_noise_scale = reset_noise_scale
        self._collision_weight = collision_weight

        parsed = tuple(assembly.Obstacle(**o) if isinstance(o, dict) else o for o in obstacles)
        self.reset_options = tuple(f"{obj}_grasp" for obj in self.objects)
        self.config = self.scene_config(teacher=teacher, obstacles=parsed, **scene)
        assembly.check_clearance(self.config)
        self.model = assembly.build_model(self.config)
        self.data = mujoco.MjData(self.model)
        self.dt = self.model.opt.timestep * frame_skip
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.dt}
        self._joint_qpos = np.array([self.model.joint(j).qposadr[0] for j in humanoid.JOINTS])
        self._joint_dof = np.array([self.model.joint(j).dofadr[0] for j in humanoid.JOINTS])
        servos = [self.model.actuator(j) for j in humanoid.JOINTS]
        #: ``(18,)`` [s]: how far each joint's position servo trails a target moving at a
        #: constant speed, ``(kv + joint damping) / kp`` as built; a controller that leads its
        #: targets by ``servo_lag * speed`` cancels it.
        self.servo_lag = np.array([
            (-a.biasprm[2] + self.model.dof_damping[dof]) / a.gainprm[0]
            for a, dof in zip(servos, self._joint_dof, strict=True)
        ])
        self._object_qpos = {
            obj: self.model.joint(obj).qposadr[0] for obj in self.objects
        }
        self._pairs = CollisionPairs.between(self.model, assembly.clearance_geoms(self.model))
        self._renderer: mujoco.Renderer | None = None
        self._needs_reset = True

        # float64 joint targets [rad], MuJoCo's ctrl: a planned replay's actions as computed
        ctrl = self.model.actuator_ctrlrange
        self.action_space = gym.spaces.Box(ctrl[:, 0], ctrl[:, 1], dtype=np.float64)
        n = len(humanoid.JOINTS)
        self.observation_structure = {"qpos": n, "qvel": n, **{obj: 7 for obj in self.objects}}
        # bounded where the quantity is: joint angles by their limits (and JOINT_SLACK), the
        # objects' unit quaternions by 1; velocities and positions (where the arms reach) not
        joints = gym.spaces.Box(ctrl[:, 0] - JOINT_SLACK, ctrl[:, 1] + JOINT_SLACK,
                                dtype=np.float64)
        pose = np.array([np.inf] * 3 + [1.0] * 4)
        high = np.concatenate([joints.high, np.full(n, np.inf), *(pose for _ in self.objects)])
        low = np.concatenate([joints.low, -high[n:]])
        state = gym.spaces.Box(low, high, dtype=np.float64)
        image = gym.spaces.Box(0, 255, (height, width, 3), dtype=np.uint8)
        pixels = gym.spaces.Dict({name: image for name in cameras})
        self._state_space = state
        self.observation_space = {
            "state": state,
            "pixels": gym.spaces.Dict({"pixels": pixels}),
            "pixels_agent_pos": gym.spaces.Dict({
                "pixels": pixels,
                "agent_pos": joints,
            }),
            "state_pixels": gym.spaces.Dict({"state": state, "pixels": pixels}),
        }[obs_type]

    # ---------------------------------------------------------------- gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Robot at its rest pose (plus seeded noise) holding both objects."""
        scene = self._scene(options)
        super().reset(seed=seed)
        for obj, height in zip(self.objects, scene.grasps, strict=True):
            assembly.set_grasp(self.model, "robot", obj, height)

        mujoco.mj_resetData(self.model, self.data)
        noise = self.np_random.uniform(-1, 1, len(humanoid.JOINTS)) * self._reset_noise_scale
        low, high = self.model.jnt_range[[self.model.joint(j).id for j in humanoid.JOINTS]].T
        q0 = np.clip(humanoid.rest_pose() + noise, low, high)
        self.data.qpos[self._joint_qpos] = q0
        self.data.ctrl[:] = q0
        if self.config.teacher:
            self._pose_teacher_at_rest()
        assembly.hold(self.model, self.data, "robot")
        for content in self.config.contents:
            content.reset(self.model, self.data, self.np_random)
        self._task_reset()
        mujoco.mj_forward(self.model, self.data)
        self._needs_reset = False
        return self._get_obs(), self._get_info(self._min_distance())

    def step(self, action):
        """Move the joint targets towards ``action`` (by at most ``max_target_speed * dt``)
        and simulate ``frame_skip`` physics steps."""
        if self._needs_reset:
            raise ImitateError("step() before reset(): call reset() first")
        action = np.asarray(action)
        if (
            action.dtype.kind not in "biuf"
            or action.shape != self.action_space.shape
            or not np.all(np.isfinite(action))
        ):
            raise ImitateError(
                f"action of shape {action.shape}, dtype {action.dtype} not accepted: "
                f"{self.action_space.shape} finite real joint targets [rad] in "
                f"models.humanoid.JOINTS order"
            )
        target = np.clip(action, self.action_space.low, self.action_space.high)
        reach = self.max_target_speed * self.dt  # exactly the action where within reach
        self.data.ctrl[:] = np.clip(target, self.data.ctrl - reach, self.data.ctrl + reach)
        diverged = self._simulate()
        min_distance = self._min_distance()
        info = self._get_info(min_distance)
        rewards = self._task_reward(info)
        rewards["reward_collision"] = -self._collision_weight if min_distance < 0.0 else 0.0
        info.update(rewards, diverged=diverged)
        return self._get_obs(), sum(rewards.values()), False, diverged, info

    def render(self):
        """RGB image ``(height, width, 3) uint8`` from ``camera``; without a ``render_mode``
        None, with Gymnasium's warning (as its MuJoCo envs)."""
        if self.render_mode is None:
            gym.logger.warn(
                "render() called without a render_mode: give gym.make(..., "
                "render_mode='rgb_array') for images"
            )
            return None
        return self._render(self.camera)

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ---------------------------------------------------------------- the task's part
    @classmethod
    def scene_config(
        cls, teacher: bool = False, obstacles: tuple[assembly.Obstacle, ...] = ()
    ) -> assembly.SceneConfig:
        """The scene of ``teacher`` and ``obstacles``, the objects at the task's default grasps
        (a task env with scene arguments of its own, contents or places, adds them)."""
        grasps = tuple(tasks.options(cls.task)[f"{obj}_grasp"].default for obj in cls.objects)
        return assembly.SceneConfig(
            teacher=teacher, obstacles=obstacles, objects=cls.objects, grasps=grasps,
            contact=cls.contact,
        )

    def _task_reset(self) -> None:
        """The task's part of ``reset``, after the objects are in the hands."""

    def _task_info(self) -> dict[str, Any]:
        """The task's measures for ``info``, with ``is_success``."""
        raise NotImplementedError

    def _task_reward(self, info: dict[str, Any]) -> dict[str, float]:
        """The task's reward terms by name (``reward_*``) of a step, given its ``info``."""
        raise NotImplementedError

    # ---------------------------------------------------------------- physics
    def _scene(self, options: Mapping[str, Any] | None) -> assembly.SceneConfig:
        """The scene with the reset ``options`` applied, all of them checked (nothing is set)."""
        options = {} if options is None else options
        accepted = list(self.reset_options)
        if not isinstance(options, Mapping):
            raise ImitateError(
                f"reset options={options!r} not accepted: a dict with keys from {accepted}"
            )
        unknown = sorted(set(options) - set(accepted), key=str)
        if unknown:
            raise ImitateError(f"reset options {unknown} unknown; accepted: {accepted}")
        grasps = tuple(
            options.get(name, old)
            for name, old in zip(self.reset_options, self.config.grasps, strict=True)
        )
        scene = dataclasses.replace(self.config, grasps=grasps)
        if scene != self.config:
            assembly.check_clearance(scene)
        return scene

    def _simulate(self) -> bool:
        """``frame_skip`` physics steps; whether the state diverged in them.

        MuJoCo's divergence warnings are counted afresh for the step (its reset after a
        divergence would restart the counts) and not printed; others become ``RuntimeWarning``s.
        """
        for warning in DIVERGENCE:
            self.data.warning[warning].number = 0
        caught: list[str] = []
        previous = mujoco.get_mju_user_warning()
        mujoco.set_mju_user_warning(caught.append)
        try:
            mujoco.mj_step(self.model, self.data, nstep=self.frame_skip)
        finally:
            mujoco.set_mju_user_warning(previous)
        diverged = any(self.data.warning[w].number for w in DIVERGENCE) or not (
            np.all(np.isfinite(self.data.qpos)) and np.all(np.isfinite(self.data.qvel))
        )
        for message in () if diverged else caught:
            warnings.warn(f"MuJoCo: {message}", RuntimeWarning, stacklevel=3)
        return bool(diverged)

    # ---------------------------------------------------------------- measurements
    def joint_positions(self) -> np.ndarray:
        """Robot joint angles ``(18,)`` [rad] in ``models.humanoid.JOINTS`` order (a copy)."""
        return self.data.qpos[self._joint_qpos].copy()

    def inside(self, container: str, points: np.ndarray) -> np.ndarray:
        """``(n,) bool``: which ``points`` (n, 3) [m] lie inside the object ``container``."""
        return inside(self.data, container, points)

    def _min_distance(self) -> float:
        dist, _ = signed_distances(self.model, self.data, self._pairs)
        return float(dist.min())

    def _get_obs(self):
        if self.obs_type == "state":
            return self._state()
        obs = {"pixels": {name: self._render(name) for name in self.cameras}}
        if self.obs_type == "pixels_agent_pos":
            joints = self.observation_space["agent_pos"]
            obs["agent_pos"] = np.clip(self.joint_positions(), joints.low, joints.high)
        elif self.obs_type == "state_pixels":
            obs["state"] = self._state()
        return obs

    def _state(self) -> np.ndarray:
        """The ``"state"`` observation, see ``observation_structure``, clipped to its space
        (joint angles past ``JOINT_SLACK``, quaternion components past 1 by rounding)."""
        d = self.data
        state = np.concatenate(
            [
                d.qpos[self._joint_qpos],
                d.qvel[self._joint_dof],
                *(d.qpos[adr : adr + 7] for adr in self._object_qpos.values()),
            ]
        )
        return np.clip(state, self._state_space.low, self._state_space.high)

    def _get_info(self, min_distance: float) -> dict[str, Any]:
        return {**self._task_info(), "min_distance": min_distance, "diverged": False}

    def _render(self, camera: str) -> np.ndarray:
        if self._renderer is None:
            fast = self.render_quality == "fast"
            if fast:  # read when the renderer's context is made
                quality = self.model.vis.quality
                quality.offsamples = 0
                quality.numslices, quality.numstacks = FAST_FACETS
            self._renderer = make_renderer(self.model, self.height, self.width, shadows=not fast)
            self._renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = not fast
        self._renderer.update_scene(self.data, camera)
        return self._renderer.render()

    def _pose_teacher_at_rest(self) -> None:
        """Teacher's arms hanging, hands by the hips, facing the robot."""
        for side in teacher_names.SIDES:
            hand = shoulder_position(side) + np.array([0.0, 0.0, -TEACHER_HAND_DROP])
            pose_arm(self.model, self.data, side, hand, np.array([0.0, 0.0, 0.0, 1.0]))


def check_weight(name: str, number: Any) -> None:
    """Raise ``ImitateError`` naming ``name`` unless ``number`` is a finite number >= 0."""
    if isinstance(number, bool) or not isinstance(number, Real) or not (
        0 <= float(number) < np.inf
    ):
        raise ImitateError(f"{name}={number!r} not accepted: a finite number >= 0")


def inside(data: mujoco.MjData, container: str, points: np.ndarray) -> np.ndarray:
    """``(n,) bool``: which ``points`` (n, 3) [m] lie inside the object ``container`` (a body
    of :data:`imitate.models.shapes.SHAPES`) at ``data``'s pose."""
    shape = shapes.SHAPES[container]
    frame = data.body(container)
    local = (points - frame.xpos) @ frame.xmat.reshape(3, 3)
    profile = np.transpose(shape.profile)
    radius = np.interp(local[:, 2], profile[1], profile[0])
    return (
        (local[:, 2] > 0.0)
        & (local[:, 2] < shape.height)
        & (np.hypot(local[:, 0], local[:, 1]) < radius)
    )


def _check_choice(name: str, value, accepted) -> None:
    if value not in accepted:
        raise ImitateError(f"{name}={value!r} not accepted: one of {list(accepted)}")
