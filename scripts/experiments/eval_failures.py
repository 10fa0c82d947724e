"""The failed variations of an evaluation, one line each, from its records (nothing is re-run).

Usage: ``python scripts/experiments/eval_failures.py EVAL_DIR`` (the folder ``imitate eval``
printed, e.g. ``runs/latest/eval/default-w10000-variance``): the records of its last evaluation (the
digests in its ``summary.json``) whose outcome is not ``success``.

Columns: ``id``, ``outcome``, where the obstacle was placed (``path`` or ``rand``) and its shape,
its centre ``x y`` [m], the plan's smallest clearance [mm] and its closest pair, the plan's
error in the task's critical phase [mm, deg] and the smallest score over the replays (headed by
the task's names: pour's pour phase and pour fraction, ``pour``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from imitate.envs import tasks
from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.evaluation.record import error_keys, score_keys
from imitate.evaluation.report import place
from imitate.evaluation.suite_run import last_records
from imitate.rundir.artifacts import load_json


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("eval_dir", type=Path)
    eval_dir = parser.parse_args().eval_dir
    try:
        records = last_records(eval_dir)
    except ImitateError as err:
        sys.exit(f"eval_failures.py: {err}")
    task = get_task(load_json(eval_dir / "summary.json").get("task", tasks.DEFAULT))
    error_m, error_deg = error_keys(task)
    score_min = score_keys(task)[1]
    failed = [r for r in records if r["outcome"] != "success"]
    print(f"{'id':>4} {'outcome':<16}{'obstacle':<15}{'x':>6}{'y':>7}{'plan':>8}  "
          f"{'closest pair':<28}{task.phase[:8] + ' err':>13}{' ' + task.score.name:>6}")
    print(f"{'':>4} {'':<16}{'':<15}{'[m]':>6}{'[m]':>7}{'[mm]':>8}  {'':<28}{'[mm, deg]':>13}")
    for r in failed:
        obstacle, plan = r["settings"]["obstacle"], r["plan"]
        where = {"in_path": "path", "random": "rand", "none": "-"}[place(r)]
        shape = f"{where} {obstacle['shape']}" if obstacle else where
        x, y = obstacle["pos"][:2] if obstacle else (float("nan"), float("nan"))
        print(f"{r['id']:>4} {r['outcome']:<16}{shape:<15}{x:6.3f}{y:7.3f}"
              f"{plan['min_distance_m'] * 1000:8.1f}  {' / '.join(plan['closest']):<28}"
              f"{plan[error_m] * 1000:7.1f} {plan[error_deg]:5.1f}{r[score_min]:6.2f}")
    print(f"{len(failed)} of {len(records)} variations failed")


if __name__ == "__main__":
    main()
