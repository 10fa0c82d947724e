"""Plan-to-physics clearance per variation: the clearance the plan promises, the one the replay
keeps, how deep anything physically touches, and how far the joints lag their targets.

Usage: ``python scripts/experiments/clearance_gap.py RUN_DIR [--n 20] [--seed 0]``: the first ``n``
variations of the default ``imitate eval`` suite of the run's task (seed ``seed``) on
``RUN_DIR``'s learned model, one replay each (the first of its seeds).

Columns: ``plan`` and ``physics``: smallest signed distance [mm] between the geoms that must
not touch (:func:`imitate.envs.assembly.clearance_geoms`, held objects by their hulls), in the
plan and over the replay; ``gap``: plan minus physics; ``touch``: the deepest MuJoCo contact
[mm] between the robot or a held object and anything but the liquid (``-`` when none), what
really touched whatever the hulls say; ``lag``: the largest joint target minus joint angle
[deg] over the replay, and its joint; last, the replay's score (the measure the task's success
is judged by, headed by its name: pour's pour fraction, ``pour``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import mujoco
import numpy as np

from imitate.envs.pour.liquid import particle_geoms
from imitate.envs.task import get_task
from imitate.evaluation import Suite, run_task
from imitate.evaluation.trial import physics, plan_variation
from imitate.evaluation.variation import draw, path_points
from imitate.models import humanoid
from imitate.motion.replay import measure
from imitate.stages.files import ModelFile


class Probe:
    """``on_step`` hook: the deepest contact between the robot or a held object (``held``, body
    names) and anything but a particle [m], and the largest joint lag (target minus angle) [rad]
    with its joint index."""

    def __init__(self, model: mujoco.MjModel, held: tuple[str, ...]):
        root, held = model.body(humanoid.ROOT_BODY).id, {model.body(b).id for b in held}
        body = model.geom_bodyid
        self.watched = np.array(
            [model.body_rootid[body[g]] == root or body[g] in held for g in range(model.ngeom)]
        )
        self.particle = np.isin(np.arange(model.ngeom), particle_geoms(model))
        self.touch, self.lag, self.joint = np.inf, 0.0, 0

    def __call__(self, env) -> None:
        d = env.data
        for c in d.contact[: d.ncon]:
            g1, g2 = c.geom1, c.geom2
            if (self.watched[g1] or self.watched[g2]) and not (
                self.particle[g1] or self.particle[g2]
            ):
                self.touch = min(self.touch, c.dist)
        lag = np.abs(d.ctrl - env.joint_positions())
        if lag.max() > self.lag:
            self.lag, self.joint = float(lag.max()), int(lag.argmax())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--n", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    stored = ModelFile.load_learned(args.run_dir)
    learned, gaze = stored.model, stored.gaze
    task = get_task(run_task(args.run_dir))
    suite = Suite.default(task.name)
    path = path_points(learned, gaze, suite["max_iter"], task)
    print(f"{'id':>3} {'obstacle':>9} {'plan':>7} {'physics':>7} {'gap':>6} {'touch':>6} "
          f"{'lag':>5} {'joint':<20} {task.score.name:>5}")
    print(f"{'':>3} {'':>9} {'[mm]':>7} {'[mm]':>7} {'[mm]':>6} {'[mm]':>6} {'[deg]':>5}")
    gaps, lags = [], []
    for i in range(args.n):
        variation = draw(suite, args.seed, i, path)
        plan = plan_variation(learned, gaze, variation, task)
        env = physics(variation, task)
        probe = Probe(env.model, task.objects)
        _, result, _ = measure(task, plan, env, seed=variation.replay_seeds[0], gaze=gaze,
                               options=variation.options, on_step=probe)
        where = "none" if variation.obstacle is None else (
            f"{variation.obstacle.shape[:3]} {'path' if variation.in_path else 'rand'}"
        )
        gap = plan.min_distance - result["min_distance_m"]
        touch = f"{probe.touch * 1000:6.1f}" if np.isfinite(probe.touch) else f"{'-':>6}"
        print(
            f"{i:3d} {where:>9} {plan.min_distance * 1000:7.1f} "
            f"{result['min_distance_m'] * 1000:7.1f} {gap * 1000:6.1f} {touch} "
            f"{np.degrees(probe.lag):5.2f} {humanoid.JOINTS[probe.joint]:<20} "
            f"{result[task.score.measure]:5.2f}", flush=True,
        )
        if plan.min_distance >= 0:
            gaps.append(gap * 1000)
            lags.append(np.degrees(probe.lag))
    if gaps:
        print(
            f"over the {len(gaps)} plans that keep clear: gap median {np.median(gaps):.2f} mm, "
            f"max {np.max(gaps):.2f} mm; lag median {np.median(lags):.2f} deg, max "
            f"{np.max(lags):.2f} deg"
        )


if __name__ == "__main__":
    main()
