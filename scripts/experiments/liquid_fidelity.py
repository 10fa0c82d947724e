"""How much liquid and how many solver iterations a pour's outcome needs: the same plans
replayed with cheaper physics, each outcome set beside the reference's and beside the
reference's own replay from another seed (the physics' noise floor).

    python scripts/experiments/liquid_fidelity.py [RUN_DIR] [--suite effort] [--teachers 5]
        [--n 10] [--similarity variance,uniform] [--variant particles=30 ...]

For each teacher (read as ``bench_compare.py`` reads them), variation ``0..n-1`` of the suite
(drawn with seed 0) and weighting, the variation is planned once and replayed in physics:

- ``reference``: as ``imitate compare`` replays it (its first replay seed);
- ``reseeded``: the same physics from the next seed (another initial-state noise);
- each ``--variant``: the reference's seed with ``particles=N`` (the liquid's spheres, as the
  pour task's setting) and/or MuJoCo's options (:data:`OPTIONS`): ``iterations=N``,
  ``ls_iterations=N``, ``tolerance=X``, ``solver=cg|newton|pgs``, ``cone=pyramidal|elliptic``,
  ``sleep=X`` (islands at rest sleep below this velocity), ``islands=0``; e.g.
  ``particles=30,iterations=20``.

Prints per arm the success rate, the share of variations whose outcome (and success) agrees with
the reference's, the mean absolute difference of the pour fraction and the physics' processor
seconds per replay; then the share of the reference's physics steps spent in MuJoCo's constraint
solver and collision detection (its timers). A cheaper arm is as good as the reference where it
agrees with it as often as ``reseeded`` does.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import mujoco
import numpy as np

from imitate.envs.task import get_task
from imitate.evaluation.suite import named_suite
from imitate.evaluation.suite_run import draw_jobs
from imitate.evaluation.teachers import _read, teacher_seeds
from imitate.evaluation.trial import physics, plan_variation
from imitate.motion.replay import measure
from imitate.stages.config import load_config

# MuJoCo's options a variant may set: name -> how its text is read.
OPTIONS = {
    "iterations": int, "ls_iterations": int, "tolerance": float,
    "solver": lambda v: int(getattr(mujoco.mjtSolver, f"mjSOL_{v.upper()}")),
    "cone": lambda v: int(getattr(mujoco.mjtCone, f"mjCONE_{v.upper()}")),
    "sleep": float, "islands": int,
}


def parse_variant(text: str) -> dict[str, float]:
    """``particles=30,iterations=20`` as a dict of the settings' values."""
    readers = {"particles": int, **OPTIONS}
    try:
        pairs = dict(item.split("=") for item in text.split(","))
        variant = {key: readers[key](value) for key, value in pairs.items()}
    except (ValueError, KeyError, AttributeError):
        variant = {}
    if not variant:
        sys.exit(f"--variant {text!r} not accepted: comma-separated NAME=VALUE of particles, "
                 f"{', '.join(OPTIONS)}")
    return variant


def configure(model: mujoco.MjModel, variant: dict) -> None:
    """``model``'s options set as ``variant`` says (:data:`OPTIONS`)."""
    for key, value in variant.items():
        if key == "sleep":
            model.opt.enableflags |= mujoco.mjtEnableBit.mjENBL_SLEEP
            model.opt.sleep_tolerance = value
        elif key == "islands":
            if not value:
                model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_ISLAND
        elif key != "particles":
            setattr(model.opt, key, value)


# MuJoCo's timers a step's time is split into (the rest: kinematics, inertia, actuation, ...).
TIMERS = {"constraint solver": mujoco.mjtTimer.mjTIMER_CONSTRAINT,
          "collision": mujoco.mjtTimer.mjTIMER_POS_COLLISION,
          "step": mujoco.mjtTimer.mjTIMER_STEP}


def replayed(plan, variation, task, gaze, seed: int, variant: dict) -> tuple:
    """The outcome, the pour fraction, the physics' processor seconds of one replay and MuJoCo's
    timers of its steps [s] (:data:`TIMERS`)."""
    options = {**variation.options, **{k: v for k, v in variant.items() if k == "particles"}}
    variation = dataclasses.replace(variation, options=options)
    env = physics(variation, task)
    configure(env.model, variant)
    start = time.thread_time()
    _, record, _ = measure(task, plan, env, seed=seed, gaze=gaze, options=variation.options)
    seconds = time.thread_time() - start
    timers = {name: env.data.timer[int(t)].duration for name, t in TIMERS.items()}
    outcome = task.outcome(plan.min_distance, [record], variation.options)
    return outcome, float(record[task.score.measure]), seconds, timers


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", nargs="?", default="runs/latest")
    parser.add_argument("--suite", default="effort")
    parser.add_argument("--teachers", type=int, default=5)
    parser.add_argument("--n", type=int, default=10)
    parser.add_argument("--similarity", default="variance,uniform")
    parser.add_argument("--variant", action="append", default=[])
    args = parser.parse_args()
    run = Path(args.run)
    config = load_config(run)
    task = get_task(config.task)
    seeds = teacher_seeds(config.seed, args.teachers)
    folders = [run, *(run / "eval" / "teachers" / f"seed-{s}" for s in seeds[1:])]
    models = [_read(s, f / "model.npz") for s, f in zip(seeds, folders, strict=True)]
    _, suite = named_suite(args.suite, task)
    arms = {"reference": {}, "reseeded": {}, **{v: parse_variant(v) for v in args.variant}}
    rows: dict[str, list[tuple[str, float, float]]] = {arm: [] for arm in arms}
    by_teacher = {m.seed: m.learned for m in models}
    drawn = draw_jobs(models, suite, 0, args.n)
    total = len(drawn) * args.n * len(args.similarity.split(","))
    done = 0
    for similarity in args.similarity.split(","):
        for d in drawn:
            learned = by_teacher[d.teacher]
            for drawn_variation in d.variations:
                plan_config = drawn_variation.plan.replace(similarity=similarity)
                v = dataclasses.replace(drawn_variation, plan=plan_config)
                plan = plan_variation(learned.model, learned.gaze, v, task)
                seed = v.replay_seeds[0]
                for arm, variant in arms.items():
                    arm_seed = seed + 1 if arm == "reseeded" else seed
                    rows[arm].append(replayed(plan, v, task, learned.gaze, arm_seed, variant))
                done += 1
                print(f"\r{done}/{total} variations", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    weighting = np.array([s for s in args.similarity.split(",")
                          for _ in range(len(drawn) * args.n)])
    reference = rows["reference"]
    ref_outcome = np.array([r[0] for r in reference])
    ref_score = np.array([r[1] for r in reference])
    print(f"{total} variations of {args.suite} ({args.teachers} teachers x {args.n} x "
          f"{args.similarity}), one replay each per arm")
    print(f"{'arm':28s} {'success':>8s} {'same outcome':>13s} {'same success':>13s} "
          f"{'|d pour|':>9s} {'physics s/replay':>17s}  success by weighting")
    for arm, arm_rows in rows.items():
        outcome = np.array([r[0] for r in arm_rows])
        score = np.array([r[1] for r in arm_rows])
        success = outcome == "success"
        print(f"{arm:28s} {success.mean():8.1%} {np.mean(outcome == ref_outcome):13.1%} "
              f"{np.mean(success == (ref_outcome == 'success')):13.1%} "
              f"{np.mean(np.abs(score - ref_score)):9.3f} "
              f"{np.mean([r[2] for r in arm_rows]):17.3f}  " + ", ".join(
                  f"{s} {success[weighting == s].mean():.0%}" for s in args.similarity.split(",")
              ))
    steps = {name: sum(r[3][name] for r in reference) for name in TIMERS}
    shares = ", ".join(f"{name} {steps[name] / steps['step']:.0%}" for name in TIMERS
                       if name != "step")
    print(f"the reference's physics steps by MuJoCo's timers: {shares}")


if __name__ == "__main__":
    main()
