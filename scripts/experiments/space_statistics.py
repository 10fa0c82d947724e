"""What do the demonstrations point to? Each candidate position term's invariance ratio
(:mod:`imitate.demos.space_selection`) per teacher, and the task space selected from them against
the task's declared one.

For each run (a teacher: ``demos.npz`` and ``config.json``), its demonstrations as the robot
tracked them are put in every candidate term (the places where each demonstration saw them) and
aligned by DTW; the critical phase is the task's ``critical`` of their mean in its declared space.
Prints the ratio per run and term, the selected space and whether it is the declared one or one
equivalent to it (:func:`~imitate.demos.space_selection.equivalent`), and the medians over the
runs, of the ratios and of their parts (the spread where the task is decided, the whole spread).
``--figure PNG`` draws the first run's candidates' spread across its demonstrations over the
aligned movement, the critical phase shaded, the selected terms bold.

Usage: ``python scripts/experiments/space_statistics.py RUN_DIR [RUN_DIR ...] [--figure PNG]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from imitate.demos.space_selection import aligned, equivalent, invariance, select, spread, spreads
from imitate.envs.task import get_task
from imitate.figures.plots import figure_png, use_agg
from imitate.stages.config import load_config
from imitate.stages.files import DemosFile
from imitate.taskspace import Relative, TaskSpace


def rated(
    run_dir: Path,
) -> tuple[str, dict[Relative, float], TaskSpace, dict[Relative, tuple[float, float]]]:
    """The task of ``run_dir``, its candidates' invariance ratios, the space they select and the
    ratios' parts (:func:`~imitate.demos.space_selection.spreads`)."""
    task, values, space, critical = demonstrated(run_dir)
    ratios = invariance(values, space, critical)
    return task, ratios, select(ratios, len(values)), spreads(values, space, critical)


def demonstrated(run_dir: Path) -> tuple[str, np.ndarray, TaskSpace, np.ndarray]:
    """The task of ``run_dir`` and its demonstrations in the candidates
    (:func:`~imitate.demos.space_selection.aligned`)."""
    config, cut = load_config(run_dir), DemosFile.load(run_dir)
    task = get_task(config.task)
    return (task.name, *aligned(cut.segments, cut.objects, cut.gaze, task,
                                smoothing=config.smoothing))


def draw(run_dir: Path, path: Path) -> None:
    """``run_dir``'s candidates' spread over the aligned movement, as a PNG at ``path``."""
    import matplotlib.pyplot as plt

    use_agg()
    task, values, space, critical = demonstrated(run_dir)
    chosen = select(invariance(values, space, critical), len(values))
    rate_hz = load_config(run_dir).fps
    times = np.arange(values.shape[1]) / rate_hz
    fig, ax = plt.subplots(figsize=(7.0, 3.6), layout="constrained")
    ax.fill_between(times, 0, 1, where=critical, transform=ax.get_xaxis_transform(),
                    color="0.9", label=f"{get_task(task).phase} (critical phase)")
    for term, across in spread(values, space).items():
        kept = term in chosen.terms
        ax.plot(times, 1e3 * across, lw=2.6 if kept else 1.0,
                label=term.name + (" (selected)" if kept else ""))
    ax.set(yscale="log", xlabel="aligned time [s]", ylabel="spread across demos [mm]",
           title=f"{task}, {run_dir}: each relation's spread over the movement")
    ax.legend(fontsize=8, ncols=2)
    path.write_bytes(figure_png(fig))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", type=Path)
    parser.add_argument("--figure", type=Path, help="PNG of the first run's spreads")
    args = parser.parse_args()
    if args.figure:
        draw(args.runs[0], args.figure)
    table = {run: rated(run) for run in args.runs}
    names = {t.name: t for t in next(iter(table.values()))[1]}
    print("invariance ratio in the critical phase: the demonstrations' spread there over the "
          "term's whole spread (small: they agree where the task is decided)")
    width = {n: max(9, len(n)) + 2 for n in names}  # each column its name's
    print(f"{'run':40s}" + "".join(f"{n:>{width[n]}s}" for n in names)
          + "  selected (the declared one, or equivalent?)")
    agree = framed = 0
    for run, (task, ratios, selected, _) in table.items():
        same = equivalent(selected, get_task(task).space)
        agree += same
        kept = [t for t in selected.terms if isinstance(t, Relative)]
        framed += any(t.frame for t in kept)
        print(f"{str(run)[-40:]:40s}" + "".join(f"{ratios[t]:{width[n]}.4f}"
                                                for n, t in names.items())
              + f"  {', '.join(t.name for t in kept)} ({'yes' if same else 'no'})")
    medians = {n: np.median([ratios[t] for _, ratios, _, _ in table.values()])
               for n, t in names.items()}
    print(f"{'median':40s}" + "".join(f"{m:{width[n]}.4f}" for n, m in medians.items()))
    print(f"the selected space is the declared one or equivalent for {agree} of {len(table)} "
          f"teachers; a relation in an object's own frame for {framed}")
    print("\nthe ratio's parts, medians over the runs: the spread across the demonstrations in the "
          "critical phase / over the whole movement [mm]")
    for n, t in names.items():
        agreed, whole = np.median([parts[t] for *_, parts in table.values()], axis=0)
        print(f"  {n:22s} {1e3 * agreed:6.1f} / {1e3 * whole:4.0f}")


if __name__ == "__main__":
    main()
