"""The default scene's collision (pour: the bottle into the chest) under each similarity weighting:
what the share of the change in high-variance steps can and cannot tell apart.

Usage: ``python scripts/experiments/weightings_default_scene.py RUN_DIR [--weights 300 10000]
[--sigma-max-scale 1] [--similarity variance ...]``: the run's learned model planned in the
default scene of its task at collision weight 0 and at each of ``--weights``, with each
weighting (default: every one of :data:`imitate.motion.SIMILARITIES`), the attractors alone (as
Fig. 9's sweep); nothing written.

Columns per weighting and collision weight: ``clear``: the plan's clearance [mm]; ``change``:
the largest change of the relative position from the same weighting's weight-0 plan [mm];
``at``: when [s];
``share``: the share of its square in steps of above-median GMR variance (the README's old
evidence for eq. 21); the critical-phase error from the GMR mean [mm, deg] (the task's critical
phase, headed by its name: pour's pour phase).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from imitate.envs.task import get_task
from imitate.evaluation import run_task
from imitate.models import humanoid
from imitate.motion import SIMILARITIES, PlanConfig, plan_from_model
from imitate.motion.metrics import critical_error, deviation
from imitate.motion.replay import planning_task
from imitate.stages.files import ModelFile


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--weights", type=float, nargs="+", default=[300.0, 10000.0])
    parser.add_argument("--sigma-max-scale", type=float, default=1.0)
    parser.add_argument("--similarity", nargs="+", choices=SIMILARITIES, default=SIMILARITIES)
    args = parser.parse_args()
    learned = ModelFile.load_learned(args.run_dir)
    model = learned.model
    task = get_task(run_task(args.run_dir))
    planning = planning_task(task.scene(), learned.gaze)
    print(f"{'weighting':<10} {'weight':>7} {'clear':>7} {'change':>7} {'at':>5} {'share':>6} "
          f"{task.phase[:4] + ' [mm':>9} {'deg]':>5}")
    for similarity in args.similarity:
        plans = {
            w: plan_from_model(planning, model, q0=humanoid.rest_pose(), config=PlanConfig(
                collision_weight=w, similarity=similarity, nullspace_push=False,
                sigma_max_scale=args.sigma_max_scale,
            ), critical=task.critical)
            for w in (0.0, *args.weights)
        }
        for w in args.weights:
            p = plans[w]
            d = deviation(p, plans[0.0], task.space)
            change = np.linalg.norm(p.x[:, :3] - plans[0.0].x[:, :3], axis=1)
            at = p.times[change.argmax()] - p.times[0]
            error_m, error_deg = critical_error(p, task.space, task.critical(p.mean))
            print(f"{similarity:<10} {w:7g} {p.min_distance * 1000:7.1f} "
                  f"{d['max_deviation_m'] * 1000:7.1f} {at:5.2f} "
                  f"{d['change_high_variance_share']:6.3f} {error_m * 1000:9.1f} {error_deg:5.2f}")


if __name__ == "__main__":
    main()
