"""The pour per grasp: a run's learned model reproduced with the objects held at other heights,
planned once with the actual grasp (what ``imitate optimize`` and ``imitate eval`` do) and once
with the default grasp (as if the planner ignored it), each replayed from several seeds.

Usage: ``python scripts/experiments/grasp_pour.py RUN_DIR [--seeds 3]``; no obstacle, 60 particles.
Columns: grasp heights [m]; per plan: its clearance [mm], its pour-phase task error [mm] and
the pour fraction over the replays (mean and minimum).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
from pathlib import Path

import numpy as np

from imitate.envs.assembly import GRASP_RANGE, SceneConfig
from imitate.evaluation.suite import Suite
from imitate.evaluation.trial import physics, plan_variation, replay_once
from imitate.evaluation.variation import Variation
from imitate.models import objects
from imitate.motion.metrics import pour_phase_error
from imitate.stages.files import ModelFile


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--seeds", type=int, default=3)
    args = parser.parse_args()
    stored = ModelFile.load_learned(args.run_dir)
    learned, gaze = stored.model, stored.gaze
    suite, default = Suite.default(), SceneConfig()
    grid = {obj: np.linspace(*GRASP_RANGE[obj], 3) for obj in GRASP_RANGE}
    print(f"{'bottle':>6} {'glass':>6} | {'planned with the actual grasp':^29} | "
          f"{'planned with the default grasp':^29}")
    print(f"{'[m]':>6} {'[m]':>6} | {'clear':>6} {'error':>6} {'mean':>7} {'min':>6} | "
          f"{'clear':>6} {'error':>6} {'mean':>7} {'min':>6}")
    for bottle, glass in itertools.product(grid[objects.BOTTLE], grid[objects.GLASS]):
        actual = Variation(
            id=0, obstacle=None, in_path=False, bottle_grasp=float(bottle),
            glass_grasp=float(glass), particles=60, friction_scale=1.0, damping_scale=1.0,
            mass_scale=1.0, replay_seeds=tuple(range(args.seeds)),
            collision_weight=suite["collision_weight"],
            path_length_weight=suite["path_length_weight"][0], similarity=suite["similarity"],
            max_iter=suite["max_iter"],
        )
        ignored = dataclasses.replace(
            actual, bottle_grasp=default.bottle_grasp, glass_grasp=default.glass_grasp
        )
        row = f"{bottle:6.3f} {glass:6.3f}"
        for planned in (actual, ignored):
            plan = plan_variation(learned, gaze, planned)
            env = physics(actual)
            pours = [replay_once(plan, env, actual, s, gaze)["pour_fraction"]
                     for s in actual.replay_seeds]
            env.close()
            error_m, _ = pour_phase_error(plan)
            row += (f" | {plan.min_distance * 1000:6.1f} {error_m * 1000:6.1f} "
                    f"{np.mean(pours):7.3f} {np.min(pours):6.3f}")
        print(row, flush=True)


if __name__ == "__main__":
    main()
