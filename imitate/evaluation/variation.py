"""One variation of an evaluation: its exact settings, drawn from a suite by seed and id.

Variation ``i`` of seed ``s`` comes from its own random stream ``default_rng([s, i])``, so it is
the same whatever the number of variations and whichever process draws it. An obstacle "in the
path" stands under a point that the bottom of a held object passes through when the learned
model is reproduced without the collision cost (:func:`path_points`): its footprint holds the
point and its top rises ``path_overlap`` above it, so that reproduction would run into it. The
other obstacles are placed at random over the suite's part of the table (some of them in the
path too).

The fixtures stand off the table where the same reproduction pours (:func:`free_places`): a
shelf over the bottle, its underside ``shelf_gap`` below the bottle's highest point in the pour,
and a plate under the glass, its top ``plate_gap`` above the glass's lowest point. The shelf
alone leaves the plan one way out that keeps the task, lowering both hands together (the
null-space push may find it); a plate closes it, and with the shelf squeezes the task by both
gaps.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import mujoco
import numpy as np

from imitate import defaults
from imitate.envs.assembly import Fixture, Obstacle, SceneConfig, check_clearance
from imitate.errors import ImitateError
from imitate.evaluation.suite import Suite
from imitate.learning import LearnedModel
from imitate.models import humanoid, objects
from imitate.models.scene import TABLE_HEIGHT, TABLE_X, TABLE_Y
from imitate.motion import Plan, PlanConfig, plan_from_model
from imitate.motion.kinematics import Kinematics
from imitate.motion.metrics import pour_phase
from imitate.motion.replay import planning_task
from imitate.motion.taskspace import TaskMap

__all__ = ["PourPlace", "Variation", "draw", "free_places", "path_points"]

# The held objects, whose bottoms (body origins) an obstacle in the path stands under.
PATH_BODIES = (objects.BOTTLE, objects.GLASS)
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
        bottle_grasp, glass_grasp: Grasp heights above the objects' bottoms [m].
        particles: Liquid spheres.
        friction_scale, damping_scale, mass_scale: Physics perturbations (see the suite keys).
        replay_seeds: Seeds of the physics replays (initial-state noise), one per replay.
        collision_weight: Weight of the planner's collision cost.
        path_length_weight: Weight of its joint path-length cost.
        similarity: Its similarity weighting (:data:`~imitate.motion.SIMILARITIES`).
        max_iter: Optimizer iteration limit.
        nullspace_push: Whether the planner may push through the null space
            (:attr:`PlanConfig.nullspace_push`).
        limit_margin: How far inside each joint's range the planner keeps [rad]
            (:func:`~imitate.motion.replay.narrowed_limits`): plan on :meth:`planning_task`.
        shelf: The shelf over the bottle in the pour (a :class:`Fixture`), or ``None``.
        shelf_gap: How far its underside reaches below the bottle's highest point in the pour
            at collision weight 0 [m] (``None`` without a shelf).
        plate: The plate under the glass in the pour (a :class:`Fixture`), or ``None``.
        plate_gap: How far its top rises above the glass's lowest point in the pour at
            collision weight 0 [m] (``None`` without a plate).

    The fields after ``max_iter`` have defaults: records written before them read back as the
    default planner without fixtures.
    """

    id: int
    obstacle: Obstacle | None
    in_path: bool
    bottle_grasp: float
    glass_grasp: float
    particles: int
    friction_scale: float
    damping_scale: float
    mass_scale: float
    replay_seeds: tuple[int, ...]
    collision_weight: float
    path_length_weight: float
    similarity: str
    max_iter: int
    nullspace_push: bool = defaults.NULLSPACE_PUSH
    limit_margin: float = 0.0
    shelf: Fixture | None = None
    shelf_gap: float | None = None
    plate: Fixture | None = None
    plate_gap: float | None = None

    @property
    def fixtures(self) -> tuple[Fixture, ...]:
        """Its fixtures: the shelf and the plate it has."""
        return tuple(f for f in (self.shelf, self.plate) if f is not None)

    def scene(self) -> SceneConfig:
        """The robot's scene of this variation (its obstacle, then its fixtures)."""
        return SceneConfig(
            particles=self.particles,
            obstacles=((self.obstacle,) if self.obstacle else ()) + self.fixtures,
            bottle_grasp=self.bottle_grasp,
            glass_grasp=self.glass_grasp,
        )

    def planning_task(self, gaze: np.ndarray) -> TaskMap:
        """The planner's task map in this variation's scene (:func:`planning_task`), its joint
        ranges narrowed by ``limit_margin``."""
        return planning_task(self.scene(), gaze, limit_margin=self.limit_margin)

    def plan_config(self) -> PlanConfig:
        return PlanConfig(
            collision_weight=self.collision_weight, path_length_weight=self.path_length_weight,
            similarity=self.similarity, max_iter=self.max_iter,
            nullspace_push=self.nullspace_push,
        )

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, values: dict) -> Variation:
        def shape(kind: type[Obstacle], name: str) -> Obstacle | None:
            o = values.get(name)
            return None if o is None else kind(o["shape"], tuple(o["pos"]), tuple(o["size"]))

        return cls(**{
            **values, "obstacle": shape(Obstacle, "obstacle"),
            **{name: shape(Fixture, name) for name in ("shelf", "plate") if name in values},
            "replay_seeds": tuple(values["replay_seeds"]),
        })


@dataclass(frozen=True)
class PourPlace:
    """Where the held objects are in the pour of a reproduction (:func:`free_places`), as the
    planner sees them (their hulls).

    Attributes:
        bottle_top: ``(3,)`` [m]: the highest point of the bottle over the pouring steps (its z)
            and the mean x, y of its highest point at each of those steps.
        glass_bottom: ``(3,)`` [m]: the lowest point of the glass over the pouring steps and the
            mean x, y of its lowest point at each.
    """

    bottle_top: np.ndarray
    glass_bottom: np.ndarray


def free_places(
    learned: LearnedModel, gaze: np.ndarray, max_iter: int
) -> tuple[np.ndarray, PourPlace]:
    """:func:`path_points` and where the bottle and the glass are in the pouring phase
    (:func:`~imitate.motion.metrics.pour_phase`) of one reproduction of ``learned`` at
    collision weight 0 in the default scene (eq. 21's weighting, the default planner otherwise,
    whatever a suite's: every weighting's variations stand in the same places; the weightings'
    own unconstrained pours lie a few mm apart, the fixtures' gaps are centimetres)."""
    task = planning_task(SceneConfig(), gaze)
    plan = plan_from_model(
        task, learned, q0=humanoid.rest_pose(),
        config=PlanConfig(collision_weight=0.0, max_iter=max_iter),
    )
    return _path_points(task.kin, plan), _pour_place(task.kin, plan)


def path_points(learned: LearnedModel, gaze: np.ndarray, max_iter: int) -> np.ndarray:
    """Points ``(P, 3)`` [m] over the table top that the bottoms of the held objects pass
    through when ``learned`` is reproduced at collision weight 0 in the default scene (each
    plan step's bottle and glass, in that order)."""
    return free_places(learned, gaze, max_iter)[0]


def _path_points(kin: Kinematics, plan: Plan) -> np.ndarray:
    """:func:`path_points` of ``plan`` on ``kin``."""
    passed: list[np.ndarray] = []
    for q in plan.q:
        kin.update(q)
        passed += [kin.data.body(b).xpos.copy() for b in PATH_BODIES]
    points = np.array(passed)
    (x0, x1), (y0, y1) = TABLE_X, TABLE_Y
    x, y, z = points.T
    return points[(x >= x0) & (x <= x1) & (y >= y0) & (y <= y1) & (z > TABLE_HEIGHT)]


def _pour_place(kin: Kinematics, plan: Plan) -> PourPlace:
    """Where ``plan`` pours (:class:`PourPlace`), on ``kin``."""
    tops, bottoms = [], []
    for q in plan.q[pour_phase(plan.mean)]:
        kin.update(q)
        tops.append(_extreme_point(kin, objects.BOTTLE, 1.0))
        bottoms.append(_extreme_point(kin, objects.GLASS, -1.0))
    top, bottom = np.array(tops), np.array(bottoms)
    return PourPlace(
        bottle_top=np.array([*top[:, :2].mean(axis=0), top[:, 2].max()]),
        glass_bottom=np.array([*bottom[:, :2].mean(axis=0), bottom[:, 2].min()]),
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
    suite: Suite, seed: int, index: int, path: np.ndarray, pour: PourPlace | None = None
) -> Variation:
    """Variation ``index`` of ``suite`` for ``seed``; ``path`` from :func:`path_points` (an
    obstacle drawn for the path is placed off it when ``path`` is empty), ``pour`` from
    :func:`free_places` (needed for a suite with shelves or plates). An obstacle closer than
    the planner's margin to the robot or the objects it holds at the start (the reset's noise on
    the joints can close a few millimetres) is drawn again, up to ``_OBSTACLE_DRAWS`` times,
    then left out; so is a fixture at once (its place is the pour's, not drawn).

    The draws of the keys that came later (``path_length_weight``, the fixtures) follow those
    of the others, so that a suite without them draws the same variations as before them.

    Raises:
        ImitateError: a suite with shelves or plates and no ``pour``.
    """
    if pour is None and (suite["shelf_share"] > 0 or suite["plate_share"] > 0):
        raise ImitateError(
            f"shelf_share={suite['shelf_share']} plate_share={suite['plate_share']} need the "
            "pour's place: pass draw(..., pour=free_places(learned, gaze, max_iter)[1])"
        )
    rng = np.random.default_rng([seed, index])

    def uniform(name: str) -> float:
        low, high = suite[name]
        return float(rng.uniform(low, high))

    bottle_grasp, glass_grasp = uniform("bottle_grasp"), uniform("glass_grasp")
    obstacle, in_path = None, False
    if rng.random() < suite["obstacle_share"]:
        for _ in range(_OBSTACLE_DRAWS):
            obstacle, in_path = _obstacle(suite, rng, uniform, path)
            scene = SceneConfig(
                obstacles=(obstacle,), bottle_grasp=bottle_grasp, glass_grasp=glass_grasp
            )
            try:
                check_clearance(scene, clearance=PlanConfig().margin)
                break
            except ImitateError:
                obstacle, in_path = None, False
    low, high = suite["particles"]
    particles = int(rng.integers(low, high + 1))
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
            assert pour is not None  # checked above
            fixture = _fixture(name, pour, gap)
            scene = SceneConfig(
                obstacles=(fixture,), bottle_grasp=bottle_grasp, glass_grasp=glass_grasp
            )
            try:
                check_clearance(scene, clearance=PlanConfig().margin)
                fixtures[name] = fixture, gap
            except ImitateError:
                pass
    return Variation(
        id=index,
        obstacle=obstacle,
        in_path=in_path,
        bottle_grasp=bottle_grasp,
        glass_grasp=glass_grasp,
        particles=particles,
        friction_scale=friction_scale,
        damping_scale=damping_scale,
        mass_scale=mass_scale,
        replay_seeds=replay_seeds,
        collision_weight=suite["collision_weight"],
        path_length_weight=path_length_weight,
        similarity=suite["similarity"],
        max_iter=suite["max_iter"],
        nullspace_push=suite["nullspace_push"],
        limit_margin=suite["limit_margin"],
        shelf=fixtures["shelf"][0],
        shelf_gap=fixtures["shelf"][1],
        plate=fixtures["plate"][0],
        plate_gap=fixtures["plate"][1],
    )


def _fixture(name: str, pour: PourPlace, gap: float) -> Fixture:
    """The shelf (its underside ``gap`` below the bottle's top in the pour) or the plate (its top
    ``gap`` above the glass's bottom), centred over or under that point."""
    if name == "shelf":
        x, y, top = pour.bottle_top
        return Fixture("box", (x, y, top - gap + SHELF_SIZE[2]), SHELF_SIZE)
    x, y, bottom = pour.glass_bottom
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
