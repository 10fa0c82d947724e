"""One variation, start to end: optimize the reproduction, replay it in perturbed physics from
each of its seeds, classify the outcome, and measure how far the constraints moved the task from
the unconstrained reproduction (the same model and weighting in the task's default scene,
collision weight 0 and the default path-length weight) and how far the reproduction lies from
the demonstrations in their own metric (:func:`~imitate.motion.metrics.mahalanobis`).

The task (:class:`~imitate.envs.task.Task`) builds the physics, measures each replay
(:func:`~imitate.motion.replay.measure`) and decides the outcome.
"""

from __future__ import annotations

import time
from typing import Any, cast

import mujoco
import numpy as np

from imitate.envs.bimanual import BimanualEnv
from imitate.envs.task import Task
from imitate.evaluation.record import ReplayRecord, TrialRecord, error_keys, score_keys
from imitate.evaluation.variation import Variation
from imitate.learning import LearnedModel
from imitate.learning.tpgmm import FrameModel
from imitate.models import humanoid
from imitate.motion import Plan, PlanConfig, plan_from_model
from imitate.motion.metrics import critical_error, mahalanobis, task_change
from imitate.motion.replay import measure, planning_task
from imitate.stages.files import Learned

__all__ = ["Trial", "physics", "plan_variation", "replay_once"]


def plan_variation(
    learned: LearnedModel | FrameModel, gaze: np.ndarray, variation: Variation, task: Task,
    importance: np.ndarray | None = None,
) -> Plan:
    """The reproduction of ``learned`` in the variation's scene of ``task`` (its obstacle,
    fixtures and settings) and joint ranges; ``importance`` for that weighting
    (:attr:`Learned.importance`)."""
    return plan_from_model(
        variation.planning_task(task, gaze), learned, q0=humanoid.rest_pose(),
        config=variation.plan, critical=task.critical, importance=importance,
    )


def physics(variation: Variation, task: Task, **kwargs: Any) -> BimanualEnv:
    """``task``'s env of the variation's scene, its model perturbed: every geom's sliding
    friction times ``friction_scale``, the robot's joint damping times ``damping_scale``, the
    masses and inertias of the bodies that move freely (the held objects and what they carry)
    times ``mass_scale``. ``kwargs``: more of the env's (e.g. ``obs_type``, ``width``)."""
    env = task.make_env(variation.scene(task), **kwargs)
    m = env.model
    m.geom_friction[:, 0] *= variation.friction_scale
    dofs = [m.joint(j).dofadr[0] for j in humanoid.JOINTS]
    m.dof_damping[dofs] *= variation.damping_scale
    free = m.jnt_bodyid[m.jnt_type == mujoco.mjtJoint.mjJNT_FREE]
    m.body_mass[free] *= variation.mass_scale
    m.body_inertia[free] *= variation.mass_scale
    mujoco.mj_setConst(m, env.data)
    return env


def replay_once(
    plan: Plan, variation: Variation, task: Task, seed: int, gaze: np.ndarray
) -> ReplayRecord:
    """One replay of ``plan`` in a fresh env of the variation (:func:`physics`) from ``seed``:
    ``seed``, the task's measures, ``min_distance_m``, ``diverged`` (the physics diverged and
    the replay stopped there) and ``geometry`` (the task's watcher's summary)."""
    _, record, watched = measure(
        task, plan, physics(variation, task), seed=seed, gaze=gaze, options=variation.options
    )
    return cast(ReplayRecord, {"seed": seed, **record, "geometry": watched})


class Trial:
    """Runs variations of ``task`` with one teacher's learned model; keeps its unconstrained
    reproductions.

    Args:
        learned: The teacher's learned model and its gaze frame.
        task: The task the model was learned for.
    """

    def __init__(self, learned: Learned, task: Task):
        self.learned, self.gaze, self.task = learned.planned, learned.gaze, learned.task(task)
        self.importance = learned.importance
        self._free: dict[tuple[str, int], Plan] = {}

    def free(self, similarity: str, max_iter: int) -> Plan:
        """The unconstrained reproduction with ``similarity``: the task's default scene, no
        collision cost, the default path-length weight, the full joint ranges (what a
        variation's constraints, narrowed ranges among them, move its plan from)."""
        key = (similarity, max_iter)
        if key not in self._free:
            config = PlanConfig(collision_weight=0.0, similarity=similarity, max_iter=max_iter)
            self._free[key] = plan_from_model(
                planning_task(self.task.scene(), self.gaze), self.learned,
                q0=humanoid.rest_pose(), config=config, critical=self.task.critical,
                importance=self.importance,
            )
        return self._free[key]

    def run(self, variation: Variation) -> TrialRecord:
        """Plan, replays, outcome and task change of ``variation``: the JSON-ready record of
        ``results.jsonl`` (but the suite digest and the teacher); it depends on the model and
        ``variation`` alone, timings aside."""
        task = self.task
        start = time.perf_counter()
        plan = plan_variation(self.learned, self.gaze, variation, task, self.importance)
        plan_seconds = time.perf_counter() - start
        replays = [replay_once(plan, variation, task, s, self.gaze) for s in variation.replay_seeds]
        scores = [cast(dict, r)[task.score.measure] for r in replays]
        physics_min = min(r["min_distance_m"] for r in replays)
        critical = task.critical(plan.mean)
        error = critical_error(plan, task.space, critical)
        free = self.free(variation.plan.similarity, variation.plan.max_iter)
        mean_key, min_key = score_keys(task)
        record = {
            "id": variation.id,
            "settings": variation.to_json(),
            "outcome": task.outcome(plan.min_distance, cast(list, replays), variation.options),
            mean_key: float(np.mean(scores)),
            min_key: float(np.min(scores)),
            "plan": {
                "min_distance_m": plan.min_distance,
                "closest": list(plan.closest or ()),
                "iterations": plan.n_iter,
                "converged": plan.converged,
                "nullspace_push": bool(np.any(plan.push)),
                **dict(zip(error_keys(task), error, strict=True)),
                "seconds": plan_seconds,
            },
            "change": task_change(plan, free, task.space, critical, task.phase),
            "mahalanobis": mahalanobis(plan, task.space),
            "replays": replays,
            "physics_min_distance_m": physics_min,
            "clearance_gap_m": plan.min_distance - physics_min,
            "seconds": time.perf_counter() - start,
        }
        return cast(TrialRecord, record)
