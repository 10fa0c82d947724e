"""The ``optimize`` stage: the whole-body attractor optimization at the run's collision weight
and the Fig. 9 sweep over weights (``plan.npz``)."""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from imitate.envs.task import Task
from imitate.models import humanoid
from imitate.motion import plan_from_model
from imitate.motion.metrics import critical_error, deviation
from imitate.motion.replay import planning_task
from imitate.motion.taskspace import TaskMap
from imitate.stages.config import RunConfig
from imitate.stages.files import ModelFile, PlanFile, Sweep
from imitate.stages.progress import bar


def run(run_dir: Path, config: RunConfig, task: Task) -> dict:
    """Whole-body attractor optimization at ``collision_weight``, and the Fig. 9 sweep."""
    learned = ModelFile.load_learned(run_dir)
    model = learned.planned
    task_map = planning_task(config.scene(task=task), learned.gaze)
    chosen = config.collision_weight
    weights = sorted({chosen * s for s in config.sweep} | {chosen})
    plans, seconds = {}, {}
    for w in bar(weights, desc="optimize", unit="plan"):
        start = time.perf_counter()
        plans[w] = plan_from_model(
            task_map, model, q0=humanoid.rest_pose(),
            # the sweep shows the paper's optimizer, the attractors alone (Fig. 9); the plan at
            # the chosen weight is pushed where they leave less than the margin (``--push``)
            config=config.plan_config().replace(
                collision_weight=w, nullspace_push=config.push and w == chosen
            ),
            critical=task.critical,
        )
        seconds[w] = time.perf_counter() - start
    main = plans[chosen]
    PlanFile(main, Sweep(
        weights=np.array(weights),
        x=np.array([plans[w].x for w in weights]),
        q=np.array([plans[w].q for w in weights]),
        clearance=np.array([_clearance(task_map, plans[w].q) for w in weights]),
        cost_total=tuple(plans[w].costs["total"] for w in weights),
    )).save(run_dir)
    error_m, error_deg = critical_error(main, task.space, task.critical(main.mean))
    first = plans[weights[0]]
    return {
        "optimization": {
            "collision_weight": chosen,
            "similarity": config.similarity,
            "sigma_max_scale": config.sigma_max_scale,
            "seconds": seconds[chosen],
            "iterations": main.n_iter,
            "converged": main.converged,
            "min_distance_m": main.min_distance,
            "closest_pair": list(main.closest or ()),
            **dict(zip(task.error_keys, (error_m, error_deg), strict=True)),
            "message": main.message,
            "sweep": [
                {"weight": w, "min_distance_m": plans[w].min_distance,
                 **deviation(plans[w], first, task.space)}
                for w in weights
            ],
        }
    }


def _clearance(task_map: TaskMap, q: np.ndarray) -> np.ndarray:
    """Smallest signed distance [m] between the robot, the objects and the scene at each step of
    the joint trajectory ``q`` ``(T + 1, n)``; ``(T + 1,)``, negative when penetrating."""
    distances = []
    for q_t in q:
        task_map.kin.update(q_t)
        distances.append(task_map.kin.min_distance()[0])
    return np.array(distances)
