"""Two evaluations of the same variations, paired over teachers: what changing something other
than the weighting (the task space, a setting of the run) does, where ``imitate compare``
pairs weightings.

Each folder is an ``imitate eval`` output (its ``summary.json`` and ``results.jsonl``); their
records must be the same variations (teacher seeds, ids and the suite's draws) of runs that
differ in what is compared. Prints each teacher's successes in both and the per-teacher paired
difference of the success rate and of the task's score (its mean over the replays), mean with
its 95 % t interval over teachers, the teachers on each side and the exact sign-flip
permutation p (:func:`imitate.evaluation.inference.teacher_effect`).

Usage: ``python scripts/experiments/paired_evals.py EVAL_A EVAL_B``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from imitate.envs import tasks
from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.evaluation.inference import teacher_effect
from imitate.evaluation.record import score_keys
from imitate.evaluation.suite_run import last_records
from imitate.rundir.artifacts import load_json


def draws(record: dict) -> dict:
    """A record's variation as drawn: its settings but the weighting (the run's own) and an
    obstacle's place (one in the path stands on each model's own path)."""
    settings = record["settings"]
    return {k: v for k, v in settings.items() if k != "similarity"
            and not (k == "obstacle" and settings.get("in_path"))}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("a", type=Path, help="the first evaluation's folder")
    parser.add_argument("b", type=Path, help="the second evaluation's folder")
    args = parser.parse_args(argv)
    try:
        found = [{(r["teacher"], r["id"]): r for r in last_records(folder)}
                 for folder in (args.a, args.b)]
    except ImitateError as error:
        parser.error(str(error))
    if found[0].keys() != found[1].keys() or any(
            draws(found[0][key]) != draws(found[1][key]) for key in found[0]):
        parser.error(f"{args.a} and {args.b} are not the same variations: evaluate both with "
                     "the same --suite, --n, --seed and --teachers")
    task = get_task(load_json(args.a / "summary.json").get("task", tasks.DEFAULT))
    score = score_keys(task)[0]
    teachers = sorted({teacher for teacher, _ in found[0]})
    print(f"a: {args.a}\nb: {args.b}\n")
    print(f"| teacher | a: success | b: success | a: {score} | b: {score} |")
    print("|---|---|---|---|---|")
    rates, pours = np.empty((2, len(teachers))), np.empty((2, len(teachers)))
    for i, teacher in enumerate(teachers):
        for k, records in enumerate(found):
            mine = [r for (t, _), r in records.items() if t == teacher]
            rates[k, i] = np.mean([r["outcome"] == "success" for r in mine])
            pours[k, i] = np.mean([r[score] for r in mine])
        n = sum(1 for t, _ in found[0] if t == teacher)
        print(f"| {teacher} | {rates[0, i] * n:.0f}/{n} | {rates[1, i] * n:.0f}/{n} | "
              f"{pours[0, i]:.3f} | {pours[1, i]:.3f} |")
    print("\npaired over teachers, a - b: mean [95 % t], teachers a higher / b higher / tied, "
          "permutation p")
    for label, values, scale, unit in (("success", rates, 100.0, " pp"), (score, pours, 1.0, "")):
        effect = teacher_effect(values[0] - values[1])
        interval = (f"[{effect['ci95'][0] * scale:+.3g}, {effect['ci95'][1] * scale:+.3g}]"
                    if effect["ci95"] else "[no spread]")
        print(f"{label}: {effect['mean'] * scale:+.3g}{unit} {interval}, "
              f"{effect['a_higher']} / {effect['b_higher']} / {effect['ties']}, "
              f"p {effect['p']:.2g}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
