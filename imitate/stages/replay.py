"""The ``replay`` stage: the plan in full physics from several seeds, measured and judged by
the run's task (``replay.npz``)."""

from __future__ import annotations

import dataclasses
import logging
import os
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from imitate.envs.task import Task
from imitate.envs.video import StateRecorder
from imitate.motion import Plan
from imitate.motion.replay import measure
from imitate.stages.config import RunConfig
from imitate.stages.files import ModelFile, PlanFile, Recording, ReplayFile
from imitate.stages.progress import bar

log = logging.getLogger(__name__)

APPROACH_S = 1.0  # [s] from the reset pose to the plan's start in the replay


def run(run_dir: Path, config: RunConfig, task: Task) -> dict:
    """The plan drives the robot's actuators in full physics; again from ``task.replays - 1``
    more seeds of the initial-state noise (the physics may be chaotic: the outcome asks every
    replay to succeed). The plan of the sweep's smallest collision weight (Fig. 8's top row)
    too, recorded under ``sweep0_``.

    The replays are independent: they run in threads, one per core at most (MuJoCo's
    ``mj_step`` releases the GIL), each in its own env, so their results are those of a serial
    run."""
    jobs, gaze = _replay_jobs(run_dir, config, task.replays)
    with (
        ThreadPoolExecutor(min(len(jobs), os.cpu_count() or 1)) as pool,
        bar(total=len(jobs), desc="replay", unit="replay") as progress,
    ):
        futures = [pool.submit(_physics, task, p, config, gaze, seed) for p, seed in jobs]
        for _ in as_completed(futures):
            progress.update()
        replayed = [future.result() for future in futures]
    result, record, watched, states, state_dt = replayed[0]
    records = [r for _, r, *_ in replayed[: task.replays]]
    free_states = replayed[-1][3]
    verdict = task.outcome(jobs[0][0].min_distance, records, config.options)
    for (r, *_), (_, seed) in zip(replayed, jobs, strict=True):
        if r.diverged_at is not None:
            log.warning("the physics diverged %.2f s into the replay from seed %d", r.diverged_at,
                        seed)
    recording = Recording(
        **states, state_dt=state_dt, plan_start=APPROACH_S, task_error=result.task_error,
        min_distance=result.min_distance, measures=task.record(result.info),
    )
    ReplayFile(recording, free_states).save(run_dir)
    return {
        "replay": {
            **task.report(records, watched),
            "min_distance_m": record["min_distance_m"],
            "task_err_m_max": float(task.space.distance(result.task_error).max(initial=0.0)),
            "outcome": verdict,
            "success": verdict == "success",
        }
    }


def _replay_jobs(
    run_dir: Path, config: RunConfig, replays: int
) -> tuple[list[tuple[Plan, int]], np.ndarray]:
    """The replay stage's replays as (plan, seed): the plan from ``replays`` seeds, then the
    sweep's smallest collision weight's plan; and the learned gaze ``(3, 3)``.

    Raises:
        ImitateError: ``plan.npz`` is missing, corrupt, or holds NaN or inf where it drives
            the robot."""
    planned = PlanFile.load(run_dir)
    plan, q_free = planned.plan, planned.sweep.q[0]
    gaze = ModelFile.load_learned(run_dir).gaze
    free = dataclasses.replace(
        plan, q=q_free, q_start=q_free[0], approach_bend=np.zeros_like(q_free[0]),
        x=planned.sweep.x[0],
    )
    return [(plan, config.seed + k) for k in range(replays)] + [(free, config.seed)], gaze


def _physics(task: Task, plan: Plan, config: RunConfig, gaze: np.ndarray, seed: int):
    """``plan`` replayed in a fresh env of the task (the teacher at rest across the table) from
    ``seed``: :func:`~imitate.motion.replay.measure`'s result, record and watcher summary, then
    the recorded states (:meth:`StateRecorder.arrays`) and their spacing [s]."""
    env = task.make_env(config.scene(teacher=True, task=task))
    recorder = StateRecorder(every=max(1, round(1.0 / (config.video_fps * env.dt))))
    measured = measure(task, plan, env, seed=seed, gaze=gaze, options=config.options,
                       approach=APPROACH_S, on_step=recorder)
    return (*measured, recorder.arrays(), recorder.every * env.dt)
