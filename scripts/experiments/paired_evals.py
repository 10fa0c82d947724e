"""Two evaluations of the same variations, paired over teachers: what changing something other
than the weighting (the task space, a setting of the run) does, where ``imitate compare``
pairs weightings.

Each folder is an ``imitate eval`` output (its ``summary.json`` and ``results.jsonl``) or, as
``FOLDER:WEIGHTING``, the records of one weighting in an ``imitate compare`` output (its
``compare.json``: its teachers and variations); their records must be the same variations
(teacher seeds, ids and the suite's draws) of runs that differ in what is compared. Prints each
teacher's successes in both and the per-teacher paired difference of the success rate, of the
task's score (its mean over the replays) and of each number the task's watcher saw in every
replay (``geometry``: where the tool was when it mattered, per teacher the median over its
replays), mean with its 95 % t interval over teachers, the teachers on each side and the exact
sign-flip permutation p (:func:`imitate.evaluation.inference.teacher_effect`).

Usage: ``python scripts/experiments/paired_evals.py EVAL_A EVAL_B``, e.g. ``runs/auto/eval/effort
runs/latest/compare/effort:variance``
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from imitate.defaults import SIMILARITIES
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


def read(given: str) -> tuple[dict, dict]:
    """``given``'s summary (``summary.json`` or ``compare.json``) and its records by
    teacher and variation id: an evaluation's (its last), or one weighting's of a comparison
    (``FOLDER:WEIGHTING``; of its teachers and variations, the last of each, checked against the
    successes ``compare.json`` counts per teacher).

    Raises:
        ImitateError: no evaluation there, no comparison with that weighting, or records that
            are not the comparison's.
    """
    folder, _, weighting = given.rpartition(":")
    if weighting not in SIMILARITIES:
        folder = Path(given)
        return load_json(folder / "summary.json"), {
            (r["teacher"], r["id"]): r for r in last_records(folder)}
    compared = Path(folder) / "compare.json"
    if not compared.is_file():
        raise ImitateError(f"{compared} is missing: FOLDER:WEIGHTING names the folder "
                           "`imitate compare` printed (RUN_DIR/compare/<suite>)")
    summary = load_json(compared)
    if weighting not in summary["weightings"]:
        raise ImitateError(f"{folder} compared {', '.join(summary['weightings'])}, not "
                           f"{weighting}: give one of those after the colon")
    teachers, n = set(summary["teachers"]), summary["variations_per_teacher"]
    found = {}
    for line in (Path(folder) / "results.jsonl").read_text().splitlines():
        try:
            r = json.loads(line)
        except json.JSONDecodeError:  # a line an interruption cut short
            continue
        if (r.get("teacher") in teachers and r.get("id", n) < n
                and r.get("settings", {}).get("similarity") == weighting):
            found[(r["teacher"], r["id"])] = r
    counted = summary["weightings"][weighting]["by_teacher"]
    if any(sum(r["outcome"] == "success" for (t, _), r in found.items() if t == teacher)
           != counted.get(str(teacher), {}).get("success") for teacher in teachers):
        raise ImitateError(f"{folder}'s results.jsonl does not hold the successes its "
                           "compare.json counts (another comparison ran into the folder): run "
                           "that `imitate compare` again, it rereads its records")
    return summary, found


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("a", help="an evaluation's folder, or a comparison's FOLDER:WEIGHTING")
    parser.add_argument("b", help="the second, the same way")
    args = parser.parse_args(argv)
    try:
        (summary, a_found), (_, b_found) = read(args.a), read(args.b)
    except ImitateError as error:
        parser.error(str(error))
    found = [a_found, b_found]
    if not a_found:
        parser.error(f"{args.a} holds no records: run its evaluation first")
    if found[0].keys() != found[1].keys() or any(
            draws(found[0][key]) != draws(found[1][key]) for key in found[0]):
        parser.error(f"{args.a} and {args.b} are not the same variations: evaluate both with "
                     "the same --suite, --n, --seed and --teachers")
    task = get_task(summary.get("task", tasks.DEFAULT))
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
    watched = [key for key in found[0][next(iter(found[0]))]["replays"][0]["geometry"]
               if all(isinstance(replay["geometry"].get(key), (int, float))
                      for records in found for r in records.values() for replay in r["replays"])]
    medians = {key: np.array([[np.median([replay["geometry"][key] for (t, _), r in records.items()
                                          if t == teacher for replay in r["replays"]])
                               for teacher in teachers] for records in found])
               for key in watched}
    print("\npaired over teachers, a - b: mean [95 % t], teachers a higher / b higher / tied, "
          "permutation p; the watcher's numbers as each teacher's median over its replays "
          "(medians a, b over teachers)")
    rows = [("success", rates, 100.0, " pp"), (score, pours, 1.0, "")]
    for label, values, scale, unit in rows + [(key, medians[key], 1.0, "") for key in watched]:
        effect = teacher_effect(values[0] - values[1])
        interval = (f"[{effect['ci95'][0] * scale:+.3g}, {effect['ci95'][1] * scale:+.3g}]"
                    if effect["ci95"] else "[no spread]")
        print(f"{label}: {effect['mean'] * scale:+.3g}{unit} {interval}, "
              f"{effect['a_higher']} / {effect['b_higher']} / {effect['ties']}, "
              f"p {effect['p']:.2g} ({np.median(values[0]) * scale:.3g}, "
              f"{np.median(values[1]) * scale:.3g})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
