"""One variation, start to end: optimize the reproduction, replay it in perturbed physics from
each of its seeds, classify the outcome, and measure how far the constraints moved the task from
the unconstrained reproduction (the same model and weighting in the default scene, collision
weight 0 and the default path-length weight) and how far the reproduction lies from the
demonstrations in their own metric (:func:`~imitate.motion.metrics.mahalanobis`).

The outcome is :func:`imitate.envs.pour.outcome.outcome`'s.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import mujoco
import numpy as np

from imitate.envs.assembly import SceneConfig
from imitate.envs.pour.outcome import outcome
from imitate.envs.pour.geometry import PourGeometry
from imitate.envs.pour.env import PouringEnv
from imitate.evaluation.variation import Variation
from imitate.learning import LearnedModel
from imitate.models import humanoid, objects
from imitate.motion import Plan, PlanConfig, plan_from_model
from imitate.motion.metrics import mahalanobis, pour_phase_error, task_change
from imitate.motion.replay import planning_task, replay
from imitate.stages.files import Learned

__all__ = ["Trial", "physics", "plan_variation", "replay_once"]



def plan_variation(learned: LearnedModel, gaze: np.ndarray, variation: Variation) -> Plan:
    """The reproduction of ``learned`` in the variation's scene (its obstacle, fixtures and
    grasps) and joint ranges."""
    task = variation.planning_task(gaze)
    return plan_from_model(
        task, learned, q0=humanoid.rest_pose(), config=variation.plan_config()
    )


def physics(variation: Variation, **kwargs: Any) -> PouringEnv:
    """``PouringEnv`` of the variation's scene, its model perturbed: every geom's sliding
    friction times ``friction_scale``, the robot's joint damping times ``damping_scale``, the
    masses and inertias of the bottle, the glass and the particles times ``mass_scale``.
    ``kwargs``: more of the env's (e.g. ``obs_type``, ``width``, ``height``)."""
    scene = variation.scene()
    env = PouringEnv(particles=scene.particles, obstacles=scene.obstacles, **kwargs)
    m = env.model
    m.geom_friction[:, 0] *= variation.friction_scale
    dofs = [m.joint(j).dofadr[0] for j in humanoid.JOINTS]
    m.dof_damping[dofs] *= variation.damping_scale
    bodies = [objects.BOTTLE, objects.GLASS] + [
        f"{objects.PARTICLE_PREFIX}{i}" for i in range(scene.particles)
    ]
    for body in bodies:
        m.body(body).mass *= variation.mass_scale
        m.body(body).inertia *= variation.mass_scale
    mujoco.mj_setConst(m, env.data)
    return env


def replay_once(
    plan: Plan,
    env: PouringEnv,
    variation: Variation,
    seed: int,
    gaze: np.ndarray,
    on_step: Callable[[PouringEnv], None] | None = None,
) -> dict:
    """One replay of ``plan`` in ``env`` (from :func:`physics`) from ``seed``: ``{"seed",
    "pour_fraction", "spilled", "min_distance_m", "diverged", "geometry"}``; diverged: the
    physics diverged and the replay stopped there; geometry: where the stream met the glass
    (:meth:`PourGeometry.summary`)."""
    options = {"bottle_grasp": variation.bottle_grasp, "glass_grasp": variation.glass_grasp}
    geometry = PourGeometry()

    def step(env: PouringEnv) -> None:
        geometry(env)
        if on_step is not None:
            on_step(env)

    result = replay(plan, env, seed=seed, options=options, on_step=step, gaze=gaze)
    return {
        "seed": seed,
        "pour_fraction": result.pour_fraction,
        "spilled": result.spilled,
        "min_distance_m": result.min_distance,
        "diverged": result.diverged_at is not None,
        "geometry": geometry.summary(),
    }


class Trial:
    """Runs variations with one teacher's learned model; keeps its unconstrained reproductions.

    Args:
        learned: The teacher's learned model and its gaze frame.
    """

    def __init__(self, learned: Learned):
        self.learned, self.gaze = learned.model, learned.gaze
        self._free: dict[tuple[str, int], Plan] = {}

    def free(self, similarity: str, max_iter: int) -> Plan:
        """The unconstrained reproduction with ``similarity``: default scene, no collision
        cost, the default path-length weight, the full joint ranges (what a variation's
        constraints, narrowed ranges among them, move its plan from)."""
        key = (similarity, max_iter)
        if key not in self._free:
            config = PlanConfig(collision_weight=0.0, similarity=similarity, max_iter=max_iter)
            task = planning_task(SceneConfig(), self.gaze)
            self._free[key] = plan_from_model(
                task, self.learned, q0=humanoid.rest_pose(), config=config
            )
        return self._free[key]

    def run(self, variation: Variation) -> dict:
        """Plan, replays, outcome and task change of ``variation``: the JSON-ready record of
        ``results.jsonl`` (but the suite digest and the teacher); it depends on the model and
        ``variation`` alone, timings aside."""
        start = time.perf_counter()
        plan = plan_variation(self.learned, self.gaze, variation)
        plan_seconds = time.perf_counter() - start
        env = physics(variation)
        try:
            replays = [
                replay_once(plan, env, variation, s, self.gaze) for s in variation.replay_seeds
            ]
        finally:
            env.close()
        pours = [r["pour_fraction"] for r in replays]
        physics_min = min(r["min_distance_m"] for r in replays)
        error_m, error_deg = pour_phase_error(plan)
        change = task_change(plan, self.free(variation.similarity, variation.max_iter))
        deviation = mahalanobis(plan, self.learned.predict(plan.times)[1])
        return {
            "id": variation.id,
            "settings": variation.to_json(),
            "outcome": outcome(plan.min_distance, replays, variation.particles),
            "pour_mean": float(np.mean(pours)),
            "pour_min": float(np.min(pours)),
            "plan": {
                "min_distance_m": plan.min_distance,
                "closest": list(plan.closest or ()),
                "iterations": plan.n_iter,
                "converged": plan.converged,
                "nullspace_push": bool(np.any(plan.push)),
                "pour_phase_err_m": error_m,
                "pour_phase_err_deg": error_deg,
                "seconds": plan_seconds,
            },
            "change": change,
            "mahalanobis": deviation,
            "replays": replays,
            "physics_min_distance_m": physics_min,
            "clearance_gap_m": plan.min_distance - physics_min,
            "seconds": time.perf_counter() - start,
        }
