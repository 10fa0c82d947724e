"""The pour per grasp: a run's learned model reproduced with the objects held at other heights,
planned once with the actual grasp (what ``imitate optimize`` and ``imitate eval`` do) and once
with the default grasp (as if the planner ignored it), each replayed from several seeds.

Usage: ``python scripts/experiments/grasp_pour.py RUN_DIR [--seeds 3]``; no obstacle, the run's
task's other settings at their defaults (pour: 60 particles).
Columns: grasp heights of the tool and the target [m]; per plan: its clearance [mm], its task
error in the critical phase (pour: the pour phase) [mm] and the task's score over the replays
(pour: the pour fraction; mean and minimum).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
from pathlib import Path

import numpy as np

from imitate.envs.task import get_task
from imitate.evaluation import Suite, run_task
from imitate.evaluation.trial import plan_variation, replay_once
from imitate.evaluation.variation import Variation
from imitate.motion import PlanConfig
from imitate.motion.metrics import critical_error
from imitate.stages.files import ModelFile


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    stored = ModelFile.load_learned(args.run_dir)
    learned, gaze = stored.model, stored.gaze
    task = get_task(run_task(args.run_dir))
    suite, default = Suite.default(task.name), task.settings()
    grasps = [f"{obj}_grasp" for obj in task.objects]
    grid = [np.linspace(task.options[g].low, task.options[g].high, 3) for g in grasps]
    tool, target = task.objects
    print(f"{tool[:6]:>6} {target[:6]:>6} | {'planned with the actual grasp':^29} | "
          f"{'planned with the default grasp':^29}")
    print(f"{'[m]':>6} {'[m]':>6} | {'clear':>6} {'error':>6} {'mean':>7} {'min':>6} | "
          f"{'clear':>6} {'error':>6} {'mean':>7} {'min':>6}")
    plan_config = PlanConfig(
        collision_weight=suite["collision_weight"],
        path_length_weight=suite["path_length_weight"][0], similarity=suite["similarity"],
        max_iter=suite["max_iter"],
    )
    for heights in itertools.product(*grid):
        actual = Variation(
            id=0, obstacle=None, in_path=False,
            options={**default, **{g: float(h) for g, h in zip(grasps, heights, strict=True)}},
            friction_scale=1.0, damping_scale=1.0, mass_scale=1.0,
            replay_seeds=tuple(range(args.seeds)), plan=plan_config,
        )
        ignored = dataclasses.replace(actual, options=default)
        row = " ".join(f"{h:6.3f}" for h in heights)
        for planned in (actual, ignored):
            plan = plan_variation(learned, gaze, planned, task)
            scores = [replay_once(plan, actual, task, s, gaze)[task.score.measure]
                      for s in actual.replay_seeds]
            error_m, _ = critical_error(plan, task.space, task.critical(plan.mean))
            row += (f" | {plan.min_distance * 1000:6.1f} {error_m * 1000:6.1f} "
                    f"{np.mean(scores):7.3f} {np.min(scores):6.3f}")
        print(row, flush=True)


if __name__ == "__main__":
    main()
