"""Where does a plan's start move its task state? On the variations of a recorded evaluation or
comparison, the start as the planner makes it before that step: RMR onto the learned start, then
cleared in the task's null space (:func:`imitate.motion.approach.clear_start` without a spread).
Where it still lies within the margin of a fixed geom, the planner moves the task state too (the
demonstrations' spread at their start); elsewhere its plans are as without that step.

For each variation (each teacher's, once: the settings of ``results.jsonl``, the teachers' models
of ``RUN_DIR`` and ``RUN_DIR/eval/teachers``), prints whether the null space cleared the start,
then the count per file.

Usage: ``python scripts/experiments/start_moves.py RESULTS_JSONL RUN_DIR [--teachers N]``
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from imitate.envs.task import get_task
from imitate.evaluation.teachers import run_task
from imitate.evaluation.variation import Variation
from imitate.models import humanoid
from imitate.motion import JointLimitCost
from imitate.motion.approach import clear_start
from imitate.motion.control import reach
from imitate.stages.files import ModelFile


def pinned(record: dict, run_dir: Path, task_name: str) -> bool:
    """Whether the null space leaves the start of ``record``'s variation within the margin."""
    teacher = record["teacher"]
    folder = run_dir if teacher == 0 else run_dir / "eval" / "teachers" / f"seed-{teacher}"
    learned = ModelFile.load_learned(folder)
    variation = Variation.from_json(record["settings"])
    task = learned.task(get_task(task_name))
    task_map = variation.planning_task(task, learned.gaze)
    plan, kin = variation.plan, task_map.kin
    if plan.collision_weight == 0:  # the planner clears no start then
        return False
    start = learned.model.mean[0]
    limits = JointLimitCost(kin.lower, kin.upper, plan.control.free_ratio)
    q = reach(task_map, start, humanoid.rest_pose(), plan.control, limits)
    q = clear_start(task_map, q, start, plan.control, limits, plan.margin)
    kin.update(q)
    near = kin.distances(plan.margin)
    return bool((kin.pairs.fixed(kin.model)[near.pairs] & (near.dist < plan.margin)).any())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("results", type=Path)
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--teachers", type=int, default=10, help="teacher seeds below this")
    args = parser.parse_args()
    task_name = run_task(args.run_dir)
    seen: set[tuple[int, int]] = set()
    moved = 0
    for line in args.results.read_text().splitlines():
        record = json.loads(line)
        key = (record["teacher"], record["id"])
        if key in seen or record["teacher"] >= args.teachers:
            continue
        seen.add(key)
        moved += pinned(record, args.run_dir, task_name)
    print(f"{args.results}: {len(seen)} variations of teachers below {args.teachers} ({task_name});"
          f" the null space leaves the start within the margin in {moved}")


if __name__ == "__main__":
    main()
