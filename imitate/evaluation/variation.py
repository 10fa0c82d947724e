"""One variation of an evaluation: its exact settings, drawn from a suite by seed and id.

Variation ``i`` of seed ``s`` comes from its own random stream ``default_rng([s, i])``, so it is
the same whatever the number of variations and whichever process draws it. An obstacle "in the
path" stands under a point that the bottom of a held object passes through when the learned
model is reproduced without the collision cost (:func:`path_points`): its footprint holds the
point and its top rises ``path_overlap`` above it, so that reproduction would run into it. The
other obstacles are placed at random over the suite's part of the table (some of them in the
path too). No obstacle stands over a place of the task's scene (:func:`_off_places`).

The fixtures stand off the table where the same reproduction is in the task's critical phase
(:func:`free_places`): a shelf over the tool, its underside ``shelf_gap`` below the tool's
highest point there, and a plate under the target, its top ``plate_gap`` above the target's
lowest point. The shelf alone leaves the plan one way out that keeps the task, lowering both
hands together (the null-space push may find it); a plate closes it, and with the shelf squeezes
the task by both gaps.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import mujoco
import numpy as np

from imitate.envs.assembly import Fixture, Obstacle, SceneConfig, check_clearance
from imitate.envs.task import Task, get_task
from imitate.errors import ImitateError
from imitate.evaluation.suite import Suite
from imitate.learning import LearnedModel
from imitate.learning.tpgmm import FrameModel
from imitate.models import humanoid
from imitate.models.scene import TABLE_HEIGHT, TABLE_X, TABLE_Y
from imitate.models.shapes import SHAPES
from imitate.motion import Plan, PlanConfig, plan_from_model
from imitate.motion.kinematics import Kinematics
from imitate.motion.replay import planning_task
from imitate.motion.taskspace import TaskMap

__all__ = ["PLAN_KEYS", "CriticalPlace", "Variation", "draw", "free_places", "path_points"]

# The planner's settings a variation sets (its :class:`PlanConfig`'s), flat in its record.
PLAN_KEYS = ("collision_weight", "path_length_weight", "similarity", "max_iter", "nullspace_push")
# How far from the point an in-path obstacle's centre may lie, as a fraction of its half width.
_OFFSET = 0.8
_OBSTACLE_DRAWS = 20  # tries to draw an obstacle clear of the robot at the start
SHELF_SIZE = (0.05, 0.05, 0.05)  # a shelf's half extents [m]: a 10 cm cube
PLATE_SIZE = (0.05, 0.05, 0.01)  # a plate's half extents [m]: 10 x 10 x 2 cm


@dataclass(frozen=True)
class Variation:
    """Everything one variation depends on (one line of ``results.jsonl`` holds it).

    Attributes:
        id: Its index in the evaluation.
        obstacle: The obstacle on the table, or ``None``.
        in_path: Whether the obstacle was placed in the weight-0 path (see the module); one
            placed at random may be in it too.
        options: The task's own settings (its ``imitate.envs.tasks.options``: the grasps and
            the task's scene values) by name.
        friction_scale, damping_scale, mass_scale: Physics perturbations (see the suite keys).
        replay_seeds: Seeds of the physics replays (initial-state noise), one per replay.
        plan: The planner's settings: those of :data:`PLAN_KEYS` set, the others the defaults.
        limit_margin: How far inside each joint's range the planner keeps [rad]
            (:func:`~imitate.motion.replay.narrowed_limits`): plan on :meth:`planning_task`.
        shelf: The shelf over the tool in the critical phase (a :class:`Fixture`), or ``None``.
        shelf_gap: How far its underside reaches below the tool's highest point there at
            collision weight 0 [m] (``None`` without a shelf).
        plate: The plate under the target in the critical phase (a :class:`Fixture`), or
            ``None``.
        plate_gap: How far its top rises above the target's lowest point there at collision
            weight 0 [m] (``None`` without a plate).

    A record written before ``nullspace_push``, ``limit_margin`` and the fixtures reads back as
    the default planner without fixtures.
    """

    id: int
    obstacle: Obstacle | None
    in_path: bool
    options: dict[str, Any]
    friction_scale: float
    damping_scale: float
    mass_scale: float
    replay_seeds: tuple[int, ...]
    plan: PlanConfig
    limit_margin: float = 0.0
    shelf: Fixture | None = None
    shelf_gap: float | None = None
    plate: Fixture | None = None
    plate_gap: float | None = None

    @property
    def fixtures(self) -> tuple[Fixture, ...]:
        """Its fixtures: the shelf and the plate it has."""
        return tuple(f for f in (self.shelf, self.plate) if f is not None)

    @property
    def obstacles(self) -> tuple[Obstacle, ...]:
        """Its obstacle, then its fixtures."""
        return ((self.obstacle,) if self.obstacle else ()) + self.fixtures

    def scene(self, task: Task) -> SceneConfig:
        """The robot's scene of this variation of ``task`` (its settings and obstacles)."""
        return task.scene(self.options, self.obstacles)

    def planning_task(self, task: Task, gaze: np.ndarray | None) -> TaskMap:
        """The planner's task map in this variation's scene (:func:`planning_task`), its joint
        ranges narrowed by ``limit_margin``."""
        return planning_task(self.scene(task), gaze, limit_margin=self.limit_margin)

    def to_json(self) -> dict:
        """Its settings as a record holds them: the task's and the planner's flat among the
        others."""
        return {
            "id": self.id, "obstacle": _json(self.obstacle), "in_path": self.in_path,
            **self.options,
            "friction_scale": self.friction_scale, "damping_scale": self.damping_scale,
            "mass_scale": self.mass_scale, "replay_seeds": list(self.replay_seeds),
            **{name: getattr(self.plan, name) for name in PLAN_KEYS},
            "limit_margin": self.limit_margin,
            "shelf": _json(self.shelf), "shelf_gap": self.shelf_gap,
            "plate": _json(self.plate), "plate_gap": self.plate_gap,
        }

    @classmethod
    def from_json(cls, values: dict) -> Variation:
        """A variation's settings read back (:meth:`to_json`): the keys no field or planner's
        setting names are the task's own settings."""
        def shape(kind: type[Obstacle], name: str) -> Any:
            o = values.get(name)
            return None if o is None else kind(o["shape"], tuple(o["pos"]), tuple(o["size"]))

        known = {"id", "obstacle", "in_path", "friction_scale", "damping_scale", "mass_scale",
                 "replay_seeds", "limit_margin", "shelf", "shelf_gap", "plate", "plate_gap",
                 *PLAN_KEYS}
        plan = {k: values[k] for k in PLAN_KEYS if k in values or k != "nullspace_push"}
        return cls(
            id=values["id"], obstacle=shape(Obstacle, "obstacle"), in_path=values["in_path"],
            options={k: v for k, v in values.items() if k not in known},
            friction_scale=values["friction_scale"], damping_scale=values["damping_scale"],
            mass_scale=values["mass_scale"], replay_seeds=tuple(values["replay_seeds"]),
            plan=PlanConfig(**plan), limit_margin=values.get("limit_margin", 0.0),
            shelf=shape(Fixture, "shelf"), shelf_gap=values.get("shelf_gap"),
            plate=shape(Fixture, "plate"), plate_gap=values.get("plate_gap"),
        )


def _json(obstacle: Obstacle | None) -> dict | None:
    """An obstacle or fixture as a record holds it."""
    return None if obstacle is None else asdict(obstacle)


@dataclass(frozen=True)
class CriticalPlace:
    """Where the held objects are in the task's critical phase (``Task.critical``) of a
    reproduction (:func:`free_places`), as the planner sees them (their hulls).

    Attributes:
        tool_top: ``(3,)`` [m]: the highest point of the tool over the critical steps (its z)
            and the mean x, y of its highest point at each of those steps.
        target_bottom: ``(3,)`` [m]: the lowest point of the target over the critical steps
            and the mean x, y of its lowest point at each.
    """

    tool_top: np.ndarray
    target_bottom: np.ndarray


def free_places(
    learned: LearnedModel | FrameModel, gaze: np.ndarray, max_iter: int, task: Task
) -> tuple[np.ndarray, CriticalPlace]:
    """:func:`path_points` and where the tool and the target are in the critical phase of one
    reproduction of ``learned`` at collision weight 0 in ``task``'s default scene (eq. 21's
    weighting, the default planner otherwise, whatever a suite's: every weighting's variations
    stand in the same places; the weightings' own unconstrained reproductions lie a few mm
    apart there, the fixtures' gaps are centimetres)."""
    planning = planning_task(task.scene(), gaze)
    plan = plan_from_model(
        planning, learned, q0=humanoid.rest_pose(),
        config=PlanConfig(collision_weight=0.0, max_iter=max_iter), critical=task.critical,
    )
    return _path_points(planning.kin, plan, task), _critical_place(planning.kin, plan, task)


def path_points(
    learned: LearnedModel | FrameModel, gaze: np.ndarray, max_iter: int, task: Task
) -> np.ndarray:
    """Points ``(P, 3)`` [m] over the table top that the bottoms of the held objects pass
    through when ``learned`` is reproduced at collision weight 0 in ``task``'s default scene
    (each plan step's tool and target, in that order)."""
    return free_places(learned, gaze, max_iter, task)[0]


def _path_points(kin: Kinematics, plan: Plan, task: Task) -> np.ndarray:
    """:func:`path_points` of ``plan`` on ``kin``."""
    passed: list[np.ndarray] = []
    for q in plan.q:
        kin.update(q)
        passed += [kin.data.body(b).xpos.copy() for b in task.objects]
    points = np.array(passed)
    (x0, x1), (y0, y1) = TABLE_X, TABLE_Y
    x, y, z = points.T
    return points[(x >= x0) & (x <= x1) & (y >= y0) & (y <= y1) & (z > TABLE_HEIGHT)]


def _critical_place(kin: Kinematics, plan: Plan, task: Task) -> CriticalPlace:
    """Where ``plan`` is in ``task``'s critical phase (:class:`CriticalPlace`), on ``kin``."""
    tool, target = task.objects
    tops, bottoms = [], []
    for q in plan.q[task.critical(plan.mean)]:
        kin.update(q)
        tops.append(_extreme_point(kin, tool, 1.0))
        bottoms.append(_extreme_point(kin, target, -1.0))
    top, bottom = np.array(tops), np.array(bottoms)
    return CriticalPlace(
        tool_top=np.array([*top[:, :2].mean(axis=0), top[:, 2].max()]),
        target_bottom=np.array([*bottom[:, :2].mean(axis=0), bottom[:, 2].min()]),
    )


def _extreme_point(kin: Kinematics, body: str, up: float) -> np.ndarray:
    """The highest (``up`` 1) or lowest (-1) point ``(3,)`` [m] of ``body``'s hulls (upright
    cylinders in its frame, the geoms the planner's clearance sees) at ``kin``'s posture."""
    m, d = kin.model, kin.data
    body_id, best = m.body(body).id, None
    for g in range(m.ngeom):
        if m.geom_bodyid[g] != body_id or "_hull_" not in m.geom(g).name:
            continue
        if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_CYLINDER:
            raise ImitateError(f"hull {m.geom(g).name!r} is no cylinder; its extreme is unknown")
        radius, half = m.geom_size[g][:2]
        axis, vertical = d.geom_xmat[g].reshape(3, 3)[:, 2], np.array([0.0, 0.0, up])
        across = vertical - (vertical @ axis) * axis  # towards the extreme on the rim
        norm = np.linalg.norm(across)
        point = (
            d.geom_xpos[g] + np.copysign(half, vertical @ axis) * axis
            + (radius * across / norm if norm > 1e-9 else 0.0)
        )
        if best is None or up * point[2] > up * best[2]:
            best = point
    if best is None:
        raise ImitateError(f"body {body!r} has no hull in the planning model")
    return best


def draw(
    suite: Suite, seed: int, index: int, path: np.ndarray, place: CriticalPlace | None = None
) -> Variation:
    """Variation ``index`` of ``suite`` (of its task) for ``seed``; ``path`` from
    :func:`path_points` (an obstacle drawn for the path is placed off it when ``path`` is
    empty), ``place`` from :func:`free_places` (needed for a suite with shelves or plates). An
    obstacle closer than the planner's margin to the robot or the objects it holds at the start
    (the reset's noise on the joints can close a few millimetres) is drawn again, up to
    ``_OBSTACLE_DRAWS`` times, then left out; so is a fixture at once (its place is the critical
    phase's, not drawn).

    The task's settings that the planner sees (those of a stage before ``replay``: the grasps)
    are drawn first, the obstacle is checked against them, and the others (the physics') are
    drawn after it. The draws of the keys that came later (``path_length_weight``, the
    fixtures) follow those of the others, so that a suite without them draws the same
    variations as before them.

    Raises:
        ImitateError: a suite with shelves or plates and no ``place``.
    """
    if place is None and (suite["shelf_share"] > 0 or suite["plate_share"] > 0):
        raise ImitateError(
            f"shelf_share={suite['shelf_share']} plate_share={suite['plate_share']} need the "
            "critical phase's place: pass draw(..., place=free_places(learned, gaze, max_iter, "
            "task)[1])"
        )
    task = get_task(suite.task)
    declared = task.options
    rng = np.random.default_rng([seed, index])

    def uniform(name: str) -> float:
        low, high = suite[name]
        return float(rng.uniform(low, high))

    def option(name: str) -> float:
        low, high = suite[name]
        return int(rng.integers(low, high + 1)) if declared[name].integer else uniform(name)

    planned = [name for name, o in declared.items() if o.stage != "replay"]
    options = {name: option(name) for name in planned}
    margin = PlanConfig().margin

    def clear(obstacle: Obstacle) -> bool:
        """Whether ``obstacle`` keeps the planner's margin at the start."""
        try:
            check_clearance(task.scene(options, (obstacle,)), clearance=margin)
        except ImitateError:
            return False
        return True

    obstacle, in_path = None, False
    if rng.random() < suite["obstacle_share"]:
        for _ in range(_OBSTACLE_DRAWS):
            obstacle, in_path = _obstacle(suite, rng, uniform, path)
            if _off_places(obstacle, task.scene(options)) and clear(obstacle):
                break
            obstacle, in_path = None, False
    options.update({name: option(name) for name in declared if name not in planned})
    friction_scale, damping_scale = uniform("friction_scale"), uniform("damping_scale")
    mass_scale = uniform("mass_scale")
    replay_seeds = tuple(int(s) for s in rng.integers(0, 2**31, suite["replays"]))
    path_length_weight = uniform("path_length_weight")  # drawn after those: they stay as before
    # Each fixture's chance and gap drawn whatever its share, so that neither depends on the
    # other's share; after all of the above, which therefore stay as before the fixtures.
    fixtures: dict[str, tuple[Fixture | None, float | None]] = {}
    for name in ("shelf", "plate"):
        chance, gap = rng.random(), uniform(f"{name}_gap")
        fixtures[name] = (None, None)
        if chance < suite[f"{name}_share"]:
            assert place is not None  # checked above
            fixture = _fixture(name, place, gap)
            if clear(fixture):
                fixtures[name] = fixture, gap
    return Variation(
        id=index,
        obstacle=obstacle,
        in_path=in_path,
        options={name: options[name] for name in declared},
        friction_scale=friction_scale,
        damping_scale=damping_scale,
        mass_scale=mass_scale,
        replay_seeds=replay_seeds,
        plan=PlanConfig(
            collision_weight=suite["collision_weight"], path_length_weight=path_length_weight,
            similarity=suite["similarity"], max_iter=suite["max_iter"],
            nullspace_push=suite["nullspace_push"],
        ),
        limit_margin=suite["limit_margin"],
        shelf=fixtures["shelf"][0],
        shelf_gap=fixtures["shelf"][1],
        plate=fixtures["plate"][0],
        plate_gap=fixtures["plate"][1],
    )


def _off_places(obstacle: Obstacle, scene: SceneConfig) -> bool:
    """Whether ``obstacle``'s footprint keeps out of the column over each of ``scene``'s places
    as wide as the widest object held: a task puts an object over its place, and an obstacle
    standing there leaves no task to do (one beside the column is the task's to go round)."""
    reach = max(r for obj in scene.objects for r, _ in SHAPES[obj].profile)
    half = np.array(obstacle.size[:2] if obstacle.shape == "box" else obstacle.size[:1])
    for place in scene.places:
        apart = np.abs(np.subtract((place.x, place.y), obstacle.pos[:2]))
        gap = (np.hypot(*np.maximum(apart - half, 0.0)) if obstacle.shape == "box"
               else np.hypot(*apart) - half[0])
        if gap < reach:
            return False
    return True


def _fixture(name: str, place: CriticalPlace, gap: float) -> Fixture:
    """The shelf (its underside ``gap`` below the tool's top in the critical phase) or the plate
    (its top ``gap`` above the target's bottom), centred over or under that point."""
    if name == "shelf":
        x, y, top = place.tool_top
        return Fixture("box", (x, y, top - gap + SHELF_SIZE[2]), SHELF_SIZE)
    x, y, bottom = place.target_bottom
    return Fixture("box", (x, y, bottom + gap - PLATE_SIZE[2]), PLATE_SIZE)


def _obstacle(suite: Suite, rng: np.random.Generator, uniform, path: np.ndarray):
    """One obstacle drawn from ``suite``, its footprint on the table; whether it is in the path."""
    shape = str(rng.choice(suite["shapes"]))
    size = [uniform("obstacle_size") for _ in range(2 if shape == "box" else 1)]
    in_path = bool(rng.random() < suite["in_path_share"] and len(path))
    if in_path:
        point = path[rng.integers(len(path))]
        top = point[2] + uniform("path_overlap")
        centre = point[:2] + _offset(rng, shape, np.array(size))
        half_height = (top - TABLE_HEIGHT) / 2
    else:
        centre = np.array([uniform("obstacle_x"), uniform("obstacle_y")])
        half_height = uniform("obstacle_half_height")
    half = np.array(size if shape == "box" else size * 2)  # footprint half extents [m]
    (x0, x1), (y0, y1) = TABLE_X, TABLE_Y
    centre = np.clip(centre, (x0 + half[0], y0 + half[1]), (x1 - half[0], y1 - half[1]))
    pos = (float(centre[0]), float(centre[1]), TABLE_HEIGHT + half_height)
    return Obstacle(shape, pos, (*size, half_height)), in_path


def _offset(rng: np.random.Generator, shape: str, size: np.ndarray) -> np.ndarray:
    """A centre offset ``(2,)`` [m] that keeps the point within the obstacle's footprint."""
    if shape == "box":
        return rng.uniform(-_OFFSET, _OFFSET, 2) * size
    radius, angle = _OFFSET * size[0] * np.sqrt(rng.random()), rng.uniform(0, 2 * np.pi)
    return radius * np.array([np.cos(angle), np.sin(angle)])
