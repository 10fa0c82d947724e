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
  pour task's setting) and/or ``iterations=N`` (MuJoCo's solver iterations), e.g.
  ``particles=30,iterations=20``.

Prints per arm the success rate, the share of variations whose outcome (and success) agrees with
the reference's, the mean absolute difference of the pour fraction and the physics' processor
seconds per replay. A cheaper arm is as good as the reference where it agrees with it as often
as ``reseeded`` does.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

from imitate.envs.task import get_task
from imitate.evaluation.suite import named_suite
from imitate.evaluation.suite_run import draw_jobs
from imitate.evaluation.teachers import _read, teacher_seeds
from imitate.evaluation.trial import physics, plan_variation
from imitate.motion.replay import measure
from imitate.stages.config import load_config


def parse_variant(text: str) -> dict[str, int]:
    """``particles=30,iterations=20`` as a dict of whole numbers."""
    try:
        pairs = dict(item.split("=") for item in text.split(","))
        variant = {key: int(value) for key, value in pairs.items()}
    except ValueError:
        variant = {}
    if not variant or set(variant) - {"particles", "iterations"}:
        sys.exit(f"--variant {text!r} not accepted: particles=N and/or iterations=N, "
                 "comma-separated")
    return variant


def replayed(plan, variation, task, gaze, seed: int, variant: dict) -> tuple[str, float, float]:
    """The outcome, the pour fraction and the physics' processor seconds of one replay."""
    options = {**variation.options, **{k: v for k, v in variant.items() if k == "particles"}}
    variation = dataclasses.replace(variation, options=options)
    env = physics(variation, task)
    if "iterations" in variant:
        env.model.opt.iterations = variant["iterations"]
    start = time.thread_time()
    _, record, _ = measure(task, plan, env, seed=seed, gaze=gaze, options=variation.options)
    seconds = time.thread_time() - start
    outcome = task.outcome(plan.min_distance, [record], variation.options)
    return outcome, float(record[task.score.measure]), seconds


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


if __name__ == "__main__":
    main()
