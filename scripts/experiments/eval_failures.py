"""The failed variations of an evaluation, one line each, from its records (nothing is re-run).

Usage: ``python scripts/experiments/eval_failures.py EVAL_DIR`` (the folder ``imitate eval``
printed, e.g. ``runs/latest/eval/default-w10000-variance``): the records of its last evaluation (the
digests in its ``summary.json``) whose outcome is not ``success``.

Columns: the teacher's seed, ``id``, ``outcome``, where the obstacle was placed (``path`` or
``rand``) and its shape, its centre ``x y`` [m] and height over the table [m], the plan's
smallest clearance [mm] and its closest pair, the plan's error in the task's critical phase [mm,
deg] and the smallest score over the replays (headed by the task's names: pour's pour phase and
pour fraction, ``pour``). Then, of several teachers, the variations that more than one of them
failed, ``id: failed/teachers``: the same draws for every teacher (an obstacle in the path stands
on each model's own path, so near, not at, the same place), a scene hard for the method rather
than for one model.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

from imitate.envs import tasks
from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.evaluation.record import error_keys, score_keys
from imitate.evaluation.report import place
from imitate.evaluation.suite_run import last_records
from imitate.models.scene import TABLE_HEIGHT
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
    print(f"{'teacher':>7}{'id':>4} {'outcome':<16}{'obstacle':<15}{'x':>6}{'y':>7}{'height':>7}"
          f"{'plan':>8}  {'closest pair':<28}{task.phase[:8] + ' err':>13}"
          f"{' ' + task.score.name:>6}")
    print(f"{'':>7}{'':>4} {'':<16}{'':<15}{'[m]':>6}{'[m]':>7}{'[m]':>7}{'[mm]':>8}  {'':<28}"
          f"{'[mm, deg]':>13}")
    for r in failed:
        obstacle, plan = r["settings"]["obstacle"], r["plan"]
        where = {"in_path": "path", "random": "rand", "none": "-"}[place(r)]
        shape = f"{where} {obstacle['shape']}" if obstacle else where
        x, y, z = obstacle["pos"] if obstacle else (float("nan"),) * 3
        height = z + obstacle["size"][-1] - TABLE_HEIGHT if obstacle else float("nan")
        print(f"{r['teacher']:>7}{r['id']:>4} {r['outcome']:<16}{shape:<15}{x:6.3f}{y:7.3f}"
              f"{height:7.3f}{plan['min_distance_m'] * 1000:8.1f}  "
              f"{' / '.join(plan['closest']):<28}{plan[error_m] * 1000:7.1f} "
              f"{plan[error_deg]:5.1f}{r[score_min]:6.2f}")
    print(f"{len(failed)} of {len(records)} variations failed")
    teachers = {r["teacher"] for r in records}
    if len(teachers) > 1:
        ids = Counter(r["id"] for r in failed)
        shared = [f"{i}: {k}/{len(teachers)}" for i, k in sorted(ids.items()) if k > 1]
        print(f"failed by more than one of the {len(teachers)} teachers (id: failed/teachers): "
              f"{', '.join(shared) or 'none'}")


if __name__ == "__main__":
    main()
