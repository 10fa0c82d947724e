"""``InsertingEnv``: the humanoid puts the stick in its right hand into the glass in its left.

## Description
A fixed-base, ASIMO-like humanoid holds a stick (a narrow magenta tube, 0.30 m long) in its
right hand and a glass in its left, at a table (the teacher mannequin across it only with
``teacher=True``). Actions are joint position targets for its 18 position actuators; the physics
is MuJoCo's, objects held by weld constraints, the stick and the glass touching as solid walls
do. This is where planned movements are replayed.

## Action space
``Box(ctrl_low, ctrl_high, (18,), float64)``: target angles [rad] in ``models.humanoid.JOINTS``
order, clipped to the joint ranges. The servos' targets follow an action at ``max_target_speed``
(10 rad/s: at most 0.2 rad a step), so that random actions cannot throw the arms through the
body; planned movements (well under it) are followed exactly.

## Observation space
``obs_type="state"``: ``Box((50,), float64)``, see ``observation_structure``: robot joint angles
(18) [rad] and velocities (18) [rad/s], stick and glass poses (position [m] and quaternion wxyz, 7
each); the angles bounded by the joints' limits widened by ``JOINT_SLACK`` (MuJoCo's limits are
soft), the quaternions by 1, the rest unbounded. The robot's head cameras ``cameras``, keyed as
LeRobot's environments key theirs: ``obs_type="pixels"``: ``{"pixels": {"workspace": image}}`` by
default (the workspace camera under the eyes, looking down at the hands);
``obs_type="pixels_agent_pos"``: that and ``"agent_pos"``, the joint angles ``(18,) float64``
[rad]; ``obs_type="state_pixels"``: the ``"state"`` vector and the ``"pixels"``. Images are
``(height, width, 3) uint8`` RGB.

## Rewards
``reward_insert``: ``insert_weight`` times the increase, since the last step, of the deepest
insertion so far as a share of the success depth (capped at 1: the sum over an episode is 1 for
an insertion). ``reward_collision``: ``-collision_weight`` on every step where two geoms that
must not touch penetrate (``min_distance < 0``; the stick counts against the glass's walls,
not its solid hull, so in the glass clear of them it is no collision).
``info`` also has ``insert_depth`` (the deepest the stick's lower end has been in the glass since
the reset, below its rim [m], 0 if never), ``insert_offset`` (its distance from the glass's axis
there [m]), ``end_depth`` and ``end_offset`` (the lower end now: below the rim, negative above,
and from the axis [m], in or out of the glass), ``is_success`` (an insertion:
:func:`imitate.envs.insert.outcome.inserted`), ``min_distance`` [m] and ``diverged``.

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
| obstacles | () | ``assembly.Obstacle``s (or keyword dicts) on the table, clear of the robot |
| teacher | False | include the teacher mannequin across the table (at rest) |
| frame_skip | 10 | physics steps (2 ms each) per env step; ``metadata["render_fps"]`` = 1 / dt |
| reset_noise_scale | 0.01 | half-width of the uniform noise on the initial joint angles [rad] |
| max_target_speed | 10.0 | the joint targets' top speed towards an action [rad/s] (``inf``: none) |
| insert_weight, collision_weight | 1.0, 1.0 | reward weights |

``gym.make("imitate/Inserting-v0", **kwargs)`` passes these on; it also takes Gymnasium's own,
such as ``max_episode_steps`` (500 by default: 10 s at the default frame_skip).

## Reset options
``stick_grasp`` and ``glass_grasp``: where the hand holds each object, height above its lower
end or bottom [m] (defaults and ranges in :mod:`imitate.envs.insert.options`: the glass low, as
the left hand's collision capsule reaches into the glass). All are checked before any is
applied: a refused reset leaves the env as it was.

``step`` before the first ``reset`` raises ``ImitateError``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, ClassVar

from imitate.envs.bimanual import BimanualEnv, check_weight
from imitate.envs.insert.geometry import stick_end
from imitate.envs.insert.outcome import SUCCESS_DEPTH, inserted
from imitate.models import objects

__all__ = ["InsertingEnv"]


class InsertingEnv(BimanualEnv):
    """The insertion task in full physics (see the module docstring)."""

    task = "insert"
    objects = (objects.STICK, objects.GLASS)
    measures: ClassVar[Mapping[str, tuple[str, str]]] = {
        "insert_depth": (
            "m", "the deepest the stick's lower end went into the glass, below its rim (0: never "
            "in it)",
        ),
        "insert_offset": ("m", "its distance from the glass's axis there"),
    }
    _insert_weight: float
    _deepest: tuple[float, float]
    _progress: float
    contact = "inside"

    def __init__(self, *args: Any, insert_weight: float = 1.0, **kwargs: Any):
        check_weight("insert_weight", insert_weight)
        self._insert_weight = insert_weight
        self._deepest = (0.0, 0.0)  # depth in the glass [m], offset from its axis there [m]
        self._progress = 0.0
        super().__init__(*args, **kwargs)

    def _task_reset(self) -> None:
        self._deepest = (0.0, 0.0)
        self._progress = 0.0

    def _task_info(self) -> dict[str, Any]:
        depth, offset, inside, _ = stick_end(self.data)
        if inside > self._deepest[0]:
            self._deepest = (inside, offset)
        return {
            "insert_depth": self._deepest[0],
            "insert_offset": self._deepest[1],
            "end_depth": depth,
            "end_offset": offset,
            "is_success": inserted(self._deepest[0]),
        }

    def _task_reward(self, info: dict[str, Any]) -> dict[str, float]:
        progress = min(info["insert_depth"] / SUCCESS_DEPTH, 1.0)
        reward = self._insert_weight * (progress - self._progress)
        self._progress = progress
        return {"reward_insert": reward}
