"""``PouringEnv``: the humanoid pours from the bottle in its right hand into the glass in its left.

## Description
A fixed-base, ASIMO-like humanoid holds a bottle of liquid (small spheres) in its right hand and
a glass in its left, at a table (the teacher mannequin across it only with ``teacher=True``).
Actions are joint position targets for its 18 position actuators; the physics is MuJoCo's,
objects held by weld constraints. This is where planned movements are replayed.

## Action space
``Box(ctrl_low, ctrl_high, (18,), float32)``: target angles [rad] in ``models.humanoid.JOINTS``
order, clipped to the joint ranges.

## Observation space
``obs_type="state"``: ``Box((50,), float64)``, see ``observation_structure``: robot joint
angles (18) [rad] and velocities (18) [rad/s], bottle and glass poses (position [m] and
quaternion wxyz, 7 each). The robot's head cameras ``cameras``, keyed as LeRobot's environments
key theirs (and gym-aloha its ``pixels_agent_pos``): ``obs_type="pixels"``:
``{"pixels": {"workspace": image}}`` by default (the workspace camera under the eyes, looking
down at the hands: both objects and the pour are in view; the stereo eyes look ahead, at the
teacher when watching); ``obs_type="pixels_agent_pos"``: that and ``"agent_pos"``, the joint
angles ``(18,) float64`` [rad]; ``obs_type="state_pixels"``: the ``"state"`` vector and the
``"pixels"`` (what ``imitate export --images`` records). Images are ``(height, width, 3) uint8``
RGB.

## Rewards
``reward_pour``: ``pour_weight`` times the increase of the fraction of particles in the glass
since the last step (the sum over an episode is the final fraction). ``reward_collision``:
``-collision_weight`` on every step where two geoms that must not touch penetrate
(``min_distance < 0``). ``info`` also has ``pour_fraction``, ``spilled`` (particles in neither
container), ``is_success`` (a pour: :func:`imitate.envs.outcome.poured`), ``min_distance`` [m]
and ``diverged``.

## Episode end
Never ``terminated``. ``truncated`` (with ``info["diverged"]``) when the physics diverged in the
step: MuJoCo found a NaN, infinite or huge joint position, velocity or acceleration and reset the
state to its model defaults (its warning is not printed); reset the env. ``info["diverged"]`` is
False otherwise.

## Arguments
| argument | default | meaning |
|---|---|---|
| render_mode | None | None or ``"rgb_array"`` |
| obs_type | ``"state"`` | ``"state"``, ``"pixels"``, ``"pixels_agent_pos"`` or ``"state_pixels"`` |
| camera | ``"overview"`` | camera for ``render()``: one of ``models.scene.CAMERAS`` |
| cameras | ``("workspace",)`` | the pixel observations' cameras, of ``models.humanoid.CAMERAS`` |
| width, height | 640, 480 | image size of ``render()`` and of the head cameras' images [px] |
| particles | 60 | liquid spheres in the bottle, 0..120 |
| obstacles | () | ``assembly.Obstacle``s (or keyword dicts) on the table, clear of the robot |
| teacher | False | include the teacher mannequin across the table (at rest) |
| frame_skip | 10 | physics steps (2 ms each) per env step; ``metadata["render_fps"]`` = 1 / dt |
| reset_noise_scale | 0.01 | half-width of the uniform noise on the initial joint angles [rad] |
| pour_weight, collision_weight | 1.0, 1.0 | reward weights |

``gym.make("imitate/Pouring-v0", **kwargs)`` passes these on; it also takes Gymnasium's own,
such as ``max_episode_steps`` (500 by default: 10 s at the default frame_skip).

## Reset options
``bottle_grasp`` and ``glass_grasp``: where the hand holds each object, height above its bottom
[m] (ranges in ``imitate.envs.assembly.GRASP_RANGE``). All are checked before any is applied: a
refused reset leaves the env as it was.

``step`` before the first ``reset`` raises ``ImitateError``.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping
from numbers import Real
from typing import Any

import gymnasium as gym
import mujoco
import numpy as np

from imitate.envs import assembly
from imitate.envs.collision import CollisionPairs, signed_distances
from imitate.envs.outcome import poured
from imitate.envs.rendering import make_renderer
from imitate.envs.teacher_motion import pose_arm, shoulder_position
from imitate.errors import ImitateError
from imitate.models import humanoid, objects
from imitate.models import scene as scene_names
from imitate.models import teacher as teacher_names

OBS_TYPES = ("state", "pixels", "pixels_agent_pos", "state_pixels")
RESET_OPTIONS = ("bottle_grasp", "glass_grasp")
# MuJoCo's warnings that it found the state diverged (it then resets it).
DIVERGENCE = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
)
# How far [m] below its shoulder the teacher's hand hangs at rest (arms down, hands by the hips).
TEACHER_HAND_DROP = 0.53


class PouringEnv(gym.Env):
    """The pouring task in full physics (see the module docstring)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 50}  # 1 / dt at the default frame_skip

    def __init__(
        self,
        render_mode: str | None = None,
        obs_type: str = "state",
        camera: str = scene_names.OVERVIEW,
        cameras: tuple[str, ...] = (humanoid.WORKSPACE,),
        width: int = 640,
        height: int = 480,
        particles: int = 60,
        obstacles: tuple[assembly.Obstacle | dict, ...] = (),
        teacher: bool = False,
        frame_skip: int = 10,
        reset_noise_scale: float = 0.01,
        pour_weight: float = 1.0,
        collision_weight: float = 1.0,
    ):
        _check_choice("render_mode", render_mode, (None, *self.metadata["render_modes"]))
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
        for name, number in (
            ("reset_noise_scale", reset_noise_scale),
            ("pour_weight", pour_weight),
            ("collision_weight", collision_weight),
        ):
            if not isinstance(number, Real) or not np.isfinite(number) or number < 0:
                raise ImitateError(f"{name}={number!r} not accepted: a finite number >= 0")
        self.render_mode, self.obs_type, self.camera = render_mode, obs_type, camera
        self.cameras = cameras
        self.width, self.height = width, height
        self.frame_skip = frame_skip
        self._reset_noise_scale = reset_noise_scale
        self._pour_weight, self._collision_weight = pour_weight, collision_weight

        parsed = tuple(assembly.Obstacle(**o) if isinstance(o, dict) else o for o in obstacles)
        self.config = assembly.SceneConfig(teacher=teacher, particles=particles, obstacles=parsed)
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
            obj: self.model.joint(obj).qposadr[0] for obj in (objects.BOTTLE, objects.GLASS)
        }
        self._particle_bodies = np.array(
            [self.model.body(f"{objects.PARTICLE_PREFIX}{i}").id for i in range(particles)],
            dtype=int,
        )
        self._pairs = CollisionPairs.between(self.model, assembly.clearance_geoms(self.model))
        self._renderer: mujoco.Renderer | None = None
        self._pour_fraction = 0.0
        self._needs_reset = True

        ctrl = self.model.actuator_ctrlrange.astype(np.float32)
        self.action_space = gym.spaces.Box(ctrl[:, 0], ctrl[:, 1], dtype=np.float32)
        n = len(humanoid.JOINTS)
        self.observation_structure = {"qpos": n, "qvel": n, objects.BOTTLE: 7, objects.GLASS: 7}
        state = gym.spaces.Box(
            -np.inf, np.inf, (sum(self.observation_structure.values()),), dtype=np.float64
        )
        image = gym.spaces.Box(0, 255, (height, width, 3), dtype=np.uint8)
        pixels = gym.spaces.Dict({name: image for name in cameras})
        self.observation_space = {
            "state": state,
            "pixels": gym.spaces.Dict({"pixels": pixels}),
            "pixels_agent_pos": gym.spaces.Dict({
                "pixels": pixels,
                "agent_pos": gym.spaces.Box(-np.inf, np.inf, (n,), dtype=np.float64),
            }),
            "state_pixels": gym.spaces.Dict({"state": state, "pixels": pixels}),
        }[obs_type]

    # ---------------------------------------------------------------- gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        """Robot at its rest pose (plus seeded noise) holding both objects, bottle full."""
        scene = self._scene(options)
        super().reset(seed=seed)
        for obj in (objects.BOTTLE, objects.GLASS):
            assembly.set_grasp(self.model, "robot", obj, getattr(scene, f"{obj}_grasp"))

        mujoco.mj_resetData(self.model, self.data)
        noise = self.np_random.uniform(-1, 1, len(humanoid.JOINTS)) * self._reset_noise_scale
        low, high = self.model.jnt_range[[self.model.joint(j).id for j in humanoid.JOINTS]].T
        q0 = np.clip(humanoid.rest_pose() + noise, low, high)
        self.data.qpos[self._joint_qpos] = q0
        self.data.ctrl[:] = q0
        if self.config.teacher:
            self._pose_teacher_at_rest()
        assembly.hold(self.model, self.data, "robot")
        assembly.fill_bottle(self.model, self.data, self.np_random)
        mujoco.mj_forward(self.model, self.data)
        self._pour_fraction = self.particle_fractions()[0]
        self._needs_reset = False
        return self._get_obs(), self._get_info(self._min_distance())

    def step(self, action):
        """Apply joint targets for ``frame_skip`` physics steps."""
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
        self.data.ctrl[:] = np.clip(action, self.action_space.low, self.action_space.high)
        diverged = self._simulate()
        fraction = self.particle_fractions()[0]
        min_distance = self._min_distance()
        reward_pour = self._pour_weight * (fraction - self._pour_fraction)
        reward_collision = -self._collision_weight if min_distance < 0.0 else 0.0
        self._pour_fraction = fraction
        info = self._get_info(min_distance)
        info.update(reward_pour=reward_pour, reward_collision=reward_collision, diverged=diverged)
        return self._get_obs(), reward_pour + reward_collision, False, diverged, info

    def render(self):
        """RGB image ``(height, width, 3) uint8`` from ``camera``, or None without render_mode."""
        if self.render_mode is None:
            return None
        return self._render(self.camera)

    def close(self):
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None

    # ---------------------------------------------------------------- physics
    def _scene(self, options: Mapping[str, Any] | None) -> assembly.SceneConfig:
        """The scene with the reset ``options`` applied, all of them checked (nothing is set)."""
        options = {} if options is None else options
        if not isinstance(options, Mapping):
            raise ImitateError(
                f"reset options={options!r} not accepted: a dict with keys from "
                f"{list(RESET_OPTIONS)}"
            )
        unknown = sorted(set(options) - set(RESET_OPTIONS), key=str)
        if unknown:
            raise ImitateError(f"reset options {unknown} unknown; accepted: {list(RESET_OPTIONS)}")
        scene = dataclasses.replace(self.config, **options)
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

    @property
    def pour_fraction(self) -> float:
        """Fraction of particles inside the glass, 0..1."""
        return self._pour_fraction

    def particle_positions(self) -> np.ndarray:
        """``(n, 3)`` world positions of the liquid's particles [m]."""
        return self.data.xpos[self._particle_bodies]

    def particles_in(self, container: str) -> np.ndarray:
        """``(n,) bool``: which particles are inside ``container`` (the bottle or the glass)."""
        shape = objects.SHAPES[container]
        return _inside(self.data, container, shape, self.particle_positions())

    def particle_fractions(self) -> tuple[float, float]:
        """Fractions of particles inside the glass and inside the bottle."""
        if len(self._particle_bodies) == 0:
            return 0.0, 0.0
        return (
            float(np.mean(self.particles_in(objects.GLASS))),
            float(np.mean(self.particles_in(objects.BOTTLE))),
        )

    def _min_distance(self) -> float:
        dist, _ = signed_distances(self.model, self.data, self._pairs)
        return float(dist.min())

    def _get_obs(self):
        if self.obs_type == "state":
            return self._state()
        obs = {"pixels": {name: self._render(name) for name in self.cameras}}
        if self.obs_type == "pixels_agent_pos":
            obs["agent_pos"] = self.joint_positions()
        elif self.obs_type == "state_pixels":
            obs["state"] = self._state()
        return obs

    def _state(self) -> np.ndarray:
        """The ``"state"`` observation, see ``observation_structure``."""
        d = self.data
        return np.concatenate(
            [
                d.qpos[self._joint_qpos],
                d.qvel[self._joint_dof],
                *(d.qpos[adr : adr + 7] for adr in self._object_qpos.values()),
            ]
        )

    def _get_info(self, min_distance: float) -> dict[str, Any]:
        in_glass, in_bottle = self.particle_fractions()
        n = len(self._particle_bodies)
        return {
            "pour_fraction": in_glass,
            "spilled": int(round(n * (1.0 - in_glass - in_bottle))),
            "is_success": bool(n > 0 and poured(in_glass)),
            "min_distance": min_distance,
            "diverged": False,
        }

    def _render(self, camera: str) -> np.ndarray:
        if self._renderer is None:
            self._renderer = make_renderer(self.model, self.height, self.width)
        self._renderer.update_scene(self.data, camera)
        return self._renderer.render()

    def _pose_teacher_at_rest(self) -> None:
        """Teacher's arms hanging, hands by the hips, facing the robot."""
        for side in teacher_names.SIDES:
            hand = shoulder_position(side) + np.array([0.0, 0.0, -TEACHER_HAND_DROP])
            pose_arm(self.model, self.data, side, hand, np.array([0.0, 0.0, 0.0, 1.0]))


def _inside(data: mujoco.MjData, body: str, shape: objects.ContainerShape, points: np.ndarray):
    """Boolean ``(n,)``: which ``points`` (n, 3) [m] lie inside the container ``body``."""
    frame = data.body(body)
    local = (points - frame.xpos) @ frame.xmat.reshape(3, 3)
    radius = np.interp(local[:, 2], [z for _, z in shape.profile], [r for r, _ in shape.profile])
    return (
        (local[:, 2] > 0.0)
        & (local[:, 2] < shape.height)
        & (np.hypot(local[:, 0], local[:, 1]) < radius)
    )


def _check_choice(name: str, value, accepted) -> None:
    if value not in accepted:
        raise ImitateError(f"{name}={value!r} not accepted: one of {list(accepted)}")
