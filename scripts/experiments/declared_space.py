"""Does a task's space matter? Its teachers' demonstrations learned in the task's declared space,
in the space selected from their statistics (:mod:`imitate.demos.space_selection`), in TP-GMM's
frames (:mod:`imitate.learning.tpgmm`) and in each single relation of the tool's (to the target:
eq. 1's; to the task's first place), each reproduced over the same places.

For a task whose space is not eq. 1 (``marked``: the glass relative to the marker is part of its
space; its critical phase is found in any space, ``Task.critical_steps``), each teacher of
``RUN_DIR`` (seeds as ``imitate eval --teachers N`` takes them, learned under
``RUN_DIR/eval/teachers`` where missing) is learned again from its own cut demonstrations in
the selected space, in every candidate frame but the world (reproduced by TP-GMM's product at
each scene's places), in :data:`imitate.taskspace.EQ1` and in the tool's relation to the first
place with the angles, the target's place left to the planner (the same learning settings;
``--spaces`` picks some of these arms, :data:`SPACES`). The models
are reproduced with the default planner in the task's default scene and at ``--n`` places of
each of the task's places drawn uniformly over the built-in suite's ranges (the same draws for
all, other settings at their defaults), each replayed in physics from seeds 0, 1, 2; the outcome
is the task's. The table gives, per teacher and space, the outcome at the default place and the
successes over the drawn ones (the selected space's terms beside), then the totals with Wilson
intervals.

Usage: ``python scripts/experiments/declared_space.py RUN_DIR [--teachers 3] [--n 10]
[--seed 0] [--workers 2] [--spaces declared,selected,tpgmm,eq1,tool-place]``
"""

from __future__ import annotations

import argparse
import multiprocessing
from collections import Counter
from pathlib import Path

import numpy as np

from imitate.demos.segment import task_demos
from imitate.demos.space_selection import candidates, rate, select
from imitate.envs.task import Task, get_task
from imitate.evaluation.report import wilson
from imitate.evaluation.teachers import run_task, teachers
from imitate.learning import LearningConfig, learn
from imitate.learning.tpgmm import FrameModel
from imitate.models import humanoid
from imitate.motion import PlanConfig, plan_from_model
from imitate.motion.replay import measure, planning_task
from imitate.stages.config import load_config
from imitate.stages.files import DemosFile
from imitate.taskspace import EQ1, Relative, TaskSpace

SPACES = ("declared", "selected", "tpgmm", "eq1", "tool-place")


def model_in(run_dir: Path, space: TaskSpace):
    """The teacher's demonstrations in ``run_dir`` learned again in ``space``."""
    config, cut = load_config(run_dir), DemosFile.load(run_dir)
    demos, rate_hz = task_demos(cut.segments, cut.objects, cut.gaze, space,
                                smoothing=config.smoothing)
    settings = LearningConfig(k_max=min(config.k_max, *(len(d) for d in demos)),
                              bic_method=config.bic, seed=config.seed)
    return learn(demos, rate=rate_hz, config=settings)


def selected_space(run_dir: Path, task: Task) -> TaskSpace:
    """The space the teacher's cut demonstrations in ``run_dir`` select."""
    config, cut = load_config(run_dir), DemosFile.load(run_dir)
    ratios = rate(cut.segments, cut.objects, cut.gaze, task, smoothing=config.smoothing)
    return select(ratios, len(cut.segments))


def trial(job) -> tuple[int, int, str, str]:
    """One teacher's reproduction at one place in one space (its arm of :data:`SPACES`): its
    outcome (in a worker)."""
    seed, index, arm, space, options, model, gaze, name = job
    task = get_task(name)
    planned = task.in_space(space)
    scene = planned.scene(options)
    plan = plan_from_model(planning_task(scene, gaze), model, q0=humanoid.rest_pose(),
                           config=PlanConfig(), critical=planned.critical)
    records = [measure(planned, plan, task.make_env(scene), seed=s, gaze=gaze,
                       options=options)[1] for s in range(task.replays)]
    return seed, index, arm, task.outcome(plan.min_distance, records, task.settings(options))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--teachers", type=int, default=3)
    parser.add_argument("--n", type=int, default=10, help="drawn places per teacher")
    parser.add_argument("--seed", type=int, default=0, help="of the places' draws")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--spaces", default=",".join(SPACES), help="arms, comma-separated")
    args = parser.parse_args(argv)
    arms = tuple(args.spaces.split(","))
    if not arms or set(arms) - set(SPACES):
        parser.error(f"--spaces {args.spaces!r} not accepted: some of {', '.join(SPACES)}")
    name = run_task(args.run_dir)
    task = get_task(name)
    if task.space == EQ1:
        parser.error(f"task {name!r} declares eq. 1: nothing to compare")
    ranges = {f"{p}_{c}": task.options[f"{p}_{c}"].suite for p in task.space.places for c in "xy"}
    rng = np.random.default_rng(args.seed)
    places = [{}] + [{k: float(rng.uniform(*r)) for k, r in ranges.items()}
                     for _ in range(args.n)]
    jobs, chosen = [], {}
    for t in teachers(args.run_dir, args.run_dir / "eval", args.teachers, (), args.workers):
        chosen[t.seed] = selected_space(t.path.parent, task)
        frames = candidates(task.space.places, world=False, own_frames=False)
        spaces = {"declared": task.space, "selected": chosen[t.seed], "tpgmm": frames, "eq1": EQ1,
                  "tool-place": TaskSpace((Relative("tool", task.space.places[0]),
                                           *EQ1.terms[1:]))}
        models = {arm: t.learned.model if arm == "declared"
                  else model_in(t.path.parent, spaces[arm]) for arm in arms}
        if "tpgmm" in arms:
            models["tpgmm"] = FrameModel(models["tpgmm"], frames)
            spaces["tpgmm"] = models["tpgmm"].space
        jobs += [(t.seed, i, s, spaces[s], p, models[s], t.learned.gaze, name)
                 for i, p in enumerate(places) for s in arms]
    with multiprocessing.get_context("spawn").Pool(args.workers) as pool:
        results = pool.map(trial, jobs)
    print(f"{name}: {len(places) - 1} places drawn over {ranges} (seed {args.seed}) and the "
          f"default one; {task.replays} replays each\n")
    print("| teacher | space | default place | drawn places: success | outcomes |")
    print("|---|---|---|---|---|")
    totals = Counter()
    for seed in sorted({r[0] for r in results}):
        for space in arms:
            mine = [r for r in results if r[0] == seed and r[2] == space]
            default = next(r[3] for r in mine if r[1] == 0)
            drawn = Counter(r[3] for r in mine if r[1] > 0)
            totals[space, "success"] += drawn["success"]
            totals[space, "n"] += sum(drawn.values())
            terms = (", ".join(t.name for t in chosen[seed].terms if hasattr(t, "to"))
                     if space == "selected" else "")
            print(f"| {seed} | {space}{f' ({terms})' if terms else ''} | {default} | "
                  f"{drawn['success']} of {sum(drawn.values())}"
                  f" | {', '.join(f'{o} {k}' for o, k in drawn.most_common())} |")
    print()
    for space in arms:
        k, n = totals[space, "success"], totals[space, "n"]
        low, high = wilson(k, n)
        print(f"{space}: {k} of {n} drawn places succeed ({k / n:.0%}, 95 % Wilson "
              f"{low:.2f}..{high:.2f})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
