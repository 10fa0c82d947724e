"""Two evaluations of the same suite side by side (before and after a change), from their records.

Usage: ``python scripts/experiments/compare_evals.py BEFORE_EVAL_DIR AFTER_EVAL_DIR`` (folders
``imitate eval`` printed): the last evaluation into each (its ``summary.json``'s digests; run the
same suite, ``--n`` and ``--seed`` in both, for instance on copies of one ``model.npz`` with the
code before and after). Nothing is re-run.

Prints the successes of each, one line per variation whose outcome changed (plan and physics
clearance [mm], the smallest score: the measure the task's success is judged by, pour's pour
fraction), and the plan-minus-physics clearance [mm] of the variations whose plan is the same in
both (same clearance and iterations): there the difference is the execution's alone; then the
score over the replays of the plans that keep clear in both.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from imitate.envs import tasks
from imitate.envs.task import Task, get_task
from imitate.errors import ImitateError
from imitate.evaluation.record import score_keys
from imitate.evaluation.suite_run import last_records
from imitate.rundir.artifacts import load_json


def _state(r: dict, task: Task) -> str:
    return (f"{r['outcome']:<16}{r['plan']['min_distance_m'] * 1000:7.1f}"
            f"{r['physics_min_distance_m'] * 1000:7.1f}{r[score_keys(task)[1]]:6.2f}")


def _task(eval_dir: Path) -> Task:
    """The task of the evaluation in ``eval_dir`` (its ``summary.json``'s)."""
    return get_task(load_json(eval_dir / "summary.json").get("task", tasks.DEFAULT))


def _gaps(records: list[dict]) -> str:
    gap = np.array([r["clearance_gap_m"] for r in records]) * 1000
    return (f"median {np.median(gap):5.2f}  mean |gap| {np.abs(gap).mean():5.2f}  "
            f"p95 {np.percentile(gap, 95):5.2f}  max {gap.max():6.2f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("before", type=Path)
    parser.add_argument("after", type=Path)
    args = parser.parse_args()
    try:
        before, after = ({r["id"]: r for r in last_records(d)} for d in (args.before, args.after))
        task, other = _task(args.before), _task(args.after)
    except ImitateError as err:
        sys.exit(f"compare_evals.py: {err}")
    if task.name != other.name:
        sys.exit(f"compare_evals.py: evaluations of two tasks ({task.name}, {other.name})")
    ids = sorted(before.keys() & after.keys())
    if not ids or any(before[i]["settings"] != after[i]["settings"] for i in ids):
        sys.exit("compare_evals.py: the two evaluations do not share their variations "
                 "(run the same suite, --n and --seed)")
    for name, records in (("before", before), ("after", after)):
        wins = sum(records[i]["outcome"] == "success" for i in ids)
        print(f"{name:<7} success {wins}/{len(ids)}")
    score = " " + task.score.name  # a space before it: a name of 6 letters fills the column
    print(f"\n{'id':>4}  {'before':<16}{'plan':>7}{'phys':>7}{score:>6}   "
          f"{'after':<16}{'plan':>7}{'phys':>7}{score:>6}")
    changed = [i for i in ids if before[i]["outcome"] != after[i]["outcome"]]
    for i in changed:
        print(f"{i:>4}  {_state(before[i], task)}   {_state(after[i], task)}")
    print(f"{len(changed)} outcomes changed")
    same = [
        i for i in ids
        if before[i]["plan"]["min_distance_m"] == after[i]["plan"]["min_distance_m"] >= 0
        and before[i]["plan"]["iterations"] == after[i]["plan"]["iterations"]
    ]
    if same:
        better = sum(abs(after[i]["clearance_gap_m"]) < abs(before[i]["clearance_gap_m"])
                     for i in same)
        print(f"\nplan - physics clearance [mm] over the {len(same)} variations whose plan is "
              f"the same (clear of contact) in both:")
        print(f"  before: {_gaps([before[i] for i in same])}")
        print(f"  after:  {_gaps([after[i] for i in same])}")
        print(f"  smaller in {better} of {len(same)}")
    clear = [i for i in ids if min(before[i]["plan"]["min_distance_m"],
                                   after[i]["plan"]["min_distance_m"]) >= 0]
    print(f"\n{task.score.name} over the replays of the {len(clear)} variations whose plans "
          "keep clear in both:")
    threshold = task.score.threshold
    for name, records in (("before", before), ("after", after)):
        scores = np.array([p[task.score.measure] for i in clear for p in records[i]["replays"]])
        print(f"  {name + ':':<8}mean {scores.mean():.3f}, below {threshold:g} in "
              f"{np.sum(scores < threshold)} of {len(scores)} replays")


if __name__ == "__main__":
    main()
