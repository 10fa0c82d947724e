"""The ``replay`` stage: the plan in full physics, liquid and all, from several seeds
(``replay.npz``)."""

from __future__ import annotations

import dataclasses
import logging
import os
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

import numpy as np

from imitate.envs.outcome import outcome
from imitate.envs.pour_geometry import PourGeometry
from imitate.envs.pouring import PouringEnv
from imitate.envs.video import StateRecorder
from imitate.errors import ImitateError
from imitate.motion import Plan
from imitate.motion.replay import replay
from imitate.rundir.artifacts import load_npz, save_npz
from imitate.stages.config import RunConfig
from imitate.stages.progress import bar

log = logging.getLogger(__name__)

APPROACH_S = 1.0  # [s] from the reset pose to the plan's start in the replay
STATE_NAMES = ("qpos", "mocap_pos", "mocap_quat")  # a recorded replay state (StateRecorder)

# Replays of the pour, each from its own seed of the initial-state noise; their outcome is the
# run's (imitate.envs.outcome: the smallest pour fraction counts, one replay's is chaotic).
POUR_REPLAYS = 3


def run(run_dir: Path, config: RunConfig) -> dict:
    """The plan drives the robot's actuators in full physics, liquid and all; the pour again
    from ``POUR_REPLAYS - 1`` more seeds of the initial-state noise (it is chaotic). The plan of
    the sweep's smallest collision weight (Fig. 8's top row) too, recorded under ``sweep0_``.

    The replays are independent: they run in threads, one per core at most (MuJoCo's
    ``mj_step`` releases the GIL), each in its own env, so their results are those of a serial
    run."""
    jobs, gaze = _replay_jobs(run_dir, config)
    with (
        ThreadPoolExecutor(min(len(jobs), os.cpu_count() or 1)) as pool,
        bar(total=len(jobs), desc="replay", unit="replay") as progress,
    ):
        futures = [pool.submit(_physics, p, config, gaze, seed) for p, seed in jobs]
        for _ in as_completed(futures):
            progress.update()
        replayed = [future.result() for future in futures]
    result, states, state_dt, geometry = replayed[0]
    pours = [r.pour_fraction for r, *_ in replayed[:POUR_REPLAYS]]
    free_states = replayed[-1][1]
    verdict = outcome(jobs[0][0].min_distance, [
        {"pour_fraction": r.pour_fraction, "spilled": r.spilled, "min_distance_m": r.min_distance,
         "diverged": r.diverged_at is not None}
        for r, *_ in replayed[:POUR_REPLAYS]
    ], config.particles)
    for (r, *_), (_, seed) in zip(replayed, jobs, strict=True):
        if r.diverged_at is not None:
            log.warning("the physics diverged %.2f s into the replay from seed %d", r.diverged_at,
                        seed)
    save_npz(run_dir / "replay.npz", {
        **states, "task_error": result.task_error, "state_dt": state_dt,
        "pour_fraction": result.pour_fraction, "spilled": result.spilled,
        "min_distance": result.min_distance, "plan_start": APPROACH_S,
        **{f"sweep0_{name}": value for name, value in free_states.items()},
    })
    return {
        "replay": {
            "pour_fraction": result.pour_fraction,
            "spilled": result.spilled,
            "min_distance_m": result.min_distance,
            "task_err_m_max": float(
                np.linalg.norm(result.task_error[:, :3], axis=1).max(initial=0.0)
            ),
            "pour_fraction_mean": float(np.mean(pours)),
            "pour_fraction_min": float(np.min(pours)),
            "pour_fractions": pours,
            "outcome": verdict,
            "success": verdict == "success",
            "pour_geometry": geometry,
        }
    }


def _replay_jobs(run_dir: Path, config: RunConfig) -> tuple[list[tuple[Plan, int]], np.ndarray]:
    """The replay stage's replays as (plan, seed): the plan from ``POUR_REPLAYS`` seeds, then the
    sweep's smallest collision weight's plan; and the learned gaze ``(3, 3)``.

    Raises:
        ImitateError: ``plan.npz`` is missing, corrupt, or holds NaN or inf where it drives
            the robot."""
    path = run_dir / "plan.npz"
    driven = (*Plan.array_names(), "sweep_q", "sweep_x")
    arrays = load_npz(path, required=driven)
    bad = [name for name in driven if name != "min_distance"  # inf: nothing within range
           and arrays[name].dtype.kind in "fc" and not np.isfinite(arrays[name]).all()]
    if bad:
        raise ImitateError(
            f"{path} holds NaN or inf in {', '.join(bad[:3])}{' and more' if bad[3:] else ''}: "
            f"a plan must be finite; re-run `imitate optimize {run_dir}`"
        )
    plan = Plan.from_arrays(arrays)
    gaze = load_npz(run_dir / "model.npz", required=("gaze",))["gaze"]
    q_free = arrays["sweep_q"][0]
    free = dataclasses.replace(
        plan, q=q_free, q_start=q_free[0], approach_bend=np.zeros_like(q_free[0]),
        x=arrays["sweep_x"][0],
    )
    return [(plan, config.seed + k) for k in range(POUR_REPLAYS)] + [(free, config.seed)], gaze


def _physics(plan: Plan, config: RunConfig, gaze: np.ndarray, seed: int):
    """``plan`` replayed in a fresh ``PouringEnv`` from ``seed``: the result, the recorded
    states (:meth:`StateRecorder.arrays`), their spacing [s] and where the stream met the glass
    (:meth:`PourGeometry.summary`)."""
    env = PouringEnv(particles=config.particles, obstacles=config.scene().obstacles, teacher=True)
    recorder = StateRecorder(every=max(1, round(1.0 / (config.video_fps * env.dt))))
    geometry = PourGeometry()

    def step(env: PouringEnv) -> None:
        recorder(env)
        geometry(env)

    options = {"bottle_grasp": config.bottle_grasp, "glass_grasp": config.glass_grasp}
    result = replay(
        plan, env, seed=seed, approach=APPROACH_S, options=options, on_step=step, gaze=gaze,
    )
    env.close()
    return result, recorder.arrays(), recorder.every * env.dt, geometry.summary()
