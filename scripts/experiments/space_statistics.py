"""What do the demonstrations point to? Each candidate position term's invariance ratio
(:mod:`imitate.demos.space_selection`) per teacher, and the task space selected from them against
the task's declared one.

For each run (a teacher: ``demos.npz`` and ``config.json``), its demonstrations as the robot
tracked them are put in every candidate term (the places where each demonstration saw them) and
aligned by DTW; the critical phase is the task's ``critical`` of their mean in its declared space.
Prints the ratio per run and term, the selected space and whether it is the declared one or one
equivalent to it (:func:`~imitate.demos.space_selection.equivalent`), and the medians over the
runs.

Usage: ``python scripts/experiments/space_statistics.py RUN_DIR [RUN_DIR ...]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from imitate.demos.space_selection import equivalent, rate, select
from imitate.envs.task import get_task
from imitate.stages.config import load_config
from imitate.stages.files import DemosFile
from imitate.taskspace import Relative, TaskSpace


def rated(run_dir: Path) -> tuple[str, dict[Relative, float], TaskSpace]:
    """The task of ``run_dir``, its candidates' invariance ratios and the space they select."""
    config, cut = load_config(run_dir), DemosFile.load(run_dir)
    task = get_task(config.task)
    ratios = rate(cut.segments, cut.objects, cut.gaze, task, smoothing=config.smoothing)
    return task.name, ratios, select(ratios)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path)
    args = parser.parse_args()
    table = {run: rated(run) for run in args.runs}
    names = {f"{t.of}-{t.to}": t for t in next(iter(table.values()))[1]}
    print("invariance ratio in the critical phase: the demonstrations' spread there over the "
          "term's whole spread (small: they agree where the task is decided)")
    print(f"{'run':34s}" + "".join(f"{n:>15s}" for n in names)
          + "  selected (the declared one, or equivalent?)")
    agree = 0
    for run, (task, ratios, selected) in table.items():
        same = equivalent(selected, get_task(task).space)
        agree += same
        chosen = ", ".join(f"{t.of}-{t.to}" for t in selected.terms if isinstance(t, Relative))
        print(f"{str(run)[-34:]:34s}" + "".join(f"{ratios[t]:15.4f}" for t in names.values())
              + f"  {chosen} ({'yes' if same else 'no'})")
    medians = [np.median([ratios[t] for _, ratios, _ in table.values()]) for t in names.values()]
    print(f"{'median':34s}" + "".join(f"{m:15.4f}" for m in medians))
    print(f"the selected space is the declared one or equivalent for {agree} of {len(table)} "
          "teachers")


if __name__ == "__main__":
    main()
