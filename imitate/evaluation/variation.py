"""One variation of an evaluation: its exact settings, drawn from a suite by seed and id.

Variation ``i`` of seed ``s`` comes from its own random stream ``default_rng([s, i])``, so it is
the same whatever the number of variations and whichever process draws it. An obstacle "in the
path" stands under a point that the bottom of a held object passes through when the learned
model is reproduced without the collision cost (:func:`path_points`): its footprint holds the
point and its top rises ``path_overlap`` above it, so that reproduction would run into it. The
other obstacles are placed at random over the suite's part of the table (some of them in the
path too).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from imitate.envs.assembly import Obstacle, SceneConfig, check_clearance
from imitate.errors import ImitateError
from imitate.evaluation.suite import Suite
from imitate.learning import LearnedModel
from imitate.models import humanoid, objects
from imitate.models.scene import TABLE_HEIGHT, TABLE_X, TABLE_Y
from imitate.motion import PlanConfig, plan_from_model
from imitate.motion.replay import planning_task

__all__ = ["Variation", "draw", "path_points"]

# The held objects, whose bottoms (body origins) an obstacle in the path stands under.
PATH_BODIES = (objects.BOTTLE, objects.GLASS)
# How far from the point an in-path obstacle's centre may lie, as a fraction of its half width.
_OFFSET = 0.8
_OBSTACLE_DRAWS = 20  # tries to draw an obstacle clear of the robot at the start


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

    def scene(self) -> SceneConfig:
        """The robot's scene of this variation."""
        return SceneConfig(
            particles=self.particles,
            obstacles=(self.obstacle,) if self.obstacle else (),
            bottle_grasp=self.bottle_grasp,
            glass_grasp=self.glass_grasp,
        )

    def plan_config(self) -> PlanConfig:
        return PlanConfig(
            collision_weight=self.collision_weight, path_length_weight=self.path_length_weight,
            similarity=self.similarity, max_iter=self.max_iter,
        )

    def to_json(self) -> dict:
        return asdict(self)

    @classmethod
    def from_json(cls, values: dict) -> Variation:
        obstacle = values["obstacle"]
        if obstacle is not None:
            obstacle = Obstacle(obstacle["shape"], tuple(obstacle["pos"]), tuple(obstacle["size"]))
        return cls(**{
            **values, "obstacle": obstacle, "replay_seeds": tuple(values["replay_seeds"])
        })


def path_points(learned: LearnedModel, gaze: np.ndarray, max_iter: int) -> np.ndarray:
    """Points ``(P, 3)`` [m] over the table top that the bottoms of the held objects pass
    through when ``learned`` is reproduced at collision weight 0 in the default scene (each
    plan step's bottle and glass, in that order)."""
    task = planning_task(SceneConfig(), gaze)
    plan = plan_from_model(
        task, learned, q0=humanoid.rest_pose(),
        config=PlanConfig(collision_weight=0.0, max_iter=max_iter),
    )
    kin = task.kin
    passed: list[np.ndarray] = []
    for q in plan.q:
        kin.update(q)
        passed += [kin.data.body(b).xpos.copy() for b in PATH_BODIES]
    points = np.array(passed)
    (x0, x1), (y0, y1) = TABLE_X, TABLE_Y
    x, y, z = points.T
    return points[(x >= x0) & (x <= x1) & (y >= y0) & (y <= y1) & (z > TABLE_HEIGHT)]


def draw(suite: Suite, seed: int, index: int, path: np.ndarray) -> Variation:
    """Variation ``index`` of ``suite`` for ``seed``; ``path`` from :func:`path_points` (an
    obstacle drawn for the path is placed off it when ``path`` is empty). An obstacle closer than
    the planner's margin to the robot or the objects it holds at the start (the reset's noise on
    the joints can close a few millimetres) is drawn again, up to ``_OBSTACLE_DRAWS`` times,
    then left out."""
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
    return Variation(
        id=index,
        obstacle=obstacle,
        in_path=in_path,
        bottle_grasp=bottle_grasp,
        glass_grasp=glass_grasp,
        particles=int(rng.integers(low, high + 1)),
        friction_scale=uniform("friction_scale"),
        damping_scale=uniform("damping_scale"),
        mass_scale=uniform("mass_scale"),
        replay_seeds=tuple(int(s) for s in rng.integers(0, 2**31, suite["replays"])),
        collision_weight=suite["collision_weight"],
        path_length_weight=uniform("path_length_weight"),  # drawn last: the others as before
        similarity=suite["similarity"],
        max_iter=suite["max_iter"],
    )


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
