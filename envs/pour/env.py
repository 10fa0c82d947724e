"""``PouringEnv``: the humanoid pours from the bottle in its right hand into the glass in its left.

## Description
A fixed-base, ASIMO-like humanoid holds a bottle of liquid (small spheres) in its right hand and
a glass in its left, at a table (the teacher mannequin across it only with ``teacher=True``).
Actions are joint position targets for its 18 position actuators; the physics is MuJoCo's,
objects held by weld constraints. This is where planned movements are replayed.

## Action space
``Box(ctrl_low, ctrl_high, (18,), float64)``: target angles [rad] in ``models.humanoid.JOINTS``
order, clipped to the joint ranges. The servos' targets follow an action at ``max_target_speed``
(10 rad/s: at most 0.2 rad a step), so that random actions cannot throw the arms through the
body; planned movements (well under it) are followed exactly.

## Observation space
``obs_type="state"``: ``Box((50,), float64)``, see ``observation_structure``: robot joint angles
(18) [rad] and velocities (18) [rad/s], bottle and glass poses (position [m] and quaternion wxyz, 7
each); the angles bounded by the joints' limits widened by ``JOINT_SLACK`` (MuJoCo's limits are
soft), the quaternions by 1, the rest unbounded. The robot's head cameras ``cameras``, keyed as
LeRobot's environments key theirs (and gym-aloha its ``pixels_agent_pos``): ``obs_type="pixels"``:
``{"pixels": {"workspace": image}}`` by default (the workspace camera under the eyes, looking down
at the hands: both objects and the pour are in view; the stereo eyes look ahead, at the teacher
when watching); ``obs_type="pixels_agent_pos"``: that and ``"agent_pos"``, the joint angles
``(18,) float64`` [rad]; ``obs_type="state_pixels"``: the ``"state"`` vector and the
``"pixels"`` (what ``imitate export --images`` records). Images are ``(height, width, 3)
uint8`` RGB.

## Rewards
``reward_pour``: ``pour_weight`` times the increase of the fraction of particles in the glass
since the last step (the sum over an episode is the final fraction). ``reward_collision``:
``-collision_weight`` on every step where two geoms that must not touch penetrate
(``min_distance < 0``). ``info`` also has ``pour_fraction``, ``spilled`` (particles in neither
container), ``is_success`` (a pour: :func:`imitate.envs.pour.outcome.poured`), ``min_distance`` [m]
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
| render_quality | ``"fast"`` | ``"fast"`` (for learning: no shadows or reflections) or ``"full"`` |
| particles | 60 | liquid spheres in the bottle, 0..120 |
| obstacles | () | ``assembly.Obstacle``s (or keyword dicts) on the table, clear of the robot |
| teacher | False | include the teacher mannequin across the table (at rest) |
| frame_skip | 10 | physics steps (2 ms each) per env step; ``metadata["render_fps"]`` = 1 / dt |
| reset_noise_scale | 0.01 | half-width of the uniform noise on the initial joint angles [rad] |
| max_target_speed | 10.0 | the joint targets' top speed towards an action [rad/s] (``inf``: none) |
| pour_weight, collision_weight | 1.0, 1.0 | reward weights |

``gym.make("imitate/Pouring-v0", **kwargs)`` passes these on; it also takes Gymnasium's own,
such as ``max_episode_steps`` (500 by default: 10 s at the default frame_skip).

## Reset options
``bottle_grasp`` and ``glass_grasp``: where the hand holds each object, height above its bottom
[m] (ranges in ``imitate.models.shapes.GRASP_RANGE``). All are checked before any is applied: a
refused reset leaves the env as it was.

``step`` before the first ``reset`` raises ``ImitateError``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from imitate.envs import assembly
from imitate.envs.bimanual import BimanualEnv, check_weight
from imitate.envs.pour.liquid import Liquid, particle_bodies
from imitate.envs.pour.outcome import poured
from imitate.models import objects

__all__ = ["PouringEnv"]


class PouringEnv(BimanualEnv):
    """The pouring task in full physics (see the module docstring)."""

    task = "pour"
    objects = (objects.BOTTLE, objects.GLASS)
    measures: ClassVar[Mapping[str, tuple[str, str]]] = {
        "pour_fraction": ("1", "fraction of the particles in the glass at the end"),
        "spilled": ("-", "particles in neither container at the end"),
    }
    _pour_weight: float
    _pour_fraction: float
    _particle_bodies: np.ndarray

    def __init__(self, *args: Any, particles: int = 60, pour_weight: float = 1.0, **kwargs: Any):
        check_weight("pour_weight", pour_weight)
        self._pour_weight = pour_weight
        self._pour_fraction = 0.0
        super().__init__(*args, particles=particles, **kwargs)
        self._particle_bodies = particle_bodies(self.model)

    @classmethod
    def scene_config(
        cls, teacher: bool = False, obstacles: tuple[assembly.Obstacle, ...] = (),
        particles: int = 60,
    ) -> assembly.SceneConfig:
        """The scene with ``particles`` of :class:`~imitate.envs.pour.liquid.Liquid` in the
        bottle."""
        config = super().scene_config(teacher, obstacles)
        return dataclasses.replace(config, contents=(Liquid(particles),))

    def _task_reset(self) -> None:
        self._pour_fraction = self._fractions()[0]

    def _task_info(self) -> dict[str, Any]:
        in_glass, in_bottle = self._fractions()
        n = len(self._particle_bodies)
        return {
            "pour_fraction": in_glass,
            "spilled": int(round(n * (1.0 - in_glass - in_bottle))),
            "is_success": bool(n > 0 and poured(in_glass)),
        }

    def _task_reward(self, info: dict[str, Any]) -> dict[str, float]:
        fraction = info["pour_fraction"]
        reward = self._pour_weight * (fraction - self._pour_fraction)
        self._pour_fraction = fraction
        return {"reward_pour": reward}

    @property
    def pour_fraction(self) -> float:
        """Fraction of particles inside the glass, 0..1."""
        return self._pour_fraction

    def particle_positions(self) -> np.ndarray:
        """``(n, 3)`` world positions of the liquid's particles [m]."""
        return self.data.xpos[self._particle_bodies]

    def particles_in(self, container: str) -> np.ndarray:
        """``(n,) bool``: which particles are inside ``container`` (the bottle or the glass)."""
        return self.inside(container, self.particle_positions())

    def _fractions(self) -> tuple[float, float]:
        """Fractions of particles inside the glass and inside the bottle."""
        if len(self._particle_bodies) == 0:
            return 0.0, 0.0
        return (
            float(np.mean(self.particles_in(objects.GLASS))),
            float(np.mean(self.particles_in(objects.BOTTLE))),
        )
