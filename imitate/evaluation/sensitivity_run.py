"""``imitate sensitivity``: the task's measured tolerance of a run's teachers
(:mod:`imitate.evaluation.sensitivity`), each kept with the run, and whether the demonstrations
point at it.

For each teacher (the run's own and the next seeds, then ``confirm`` teachers of seeds 1000 and up,
learned under ``RUN_DIR/eval/teachers/`` as ``imitate eval`` learns them), its default reproduction
is moved in the critical phase along 2 m directions (14 for eq. 1) by each magnitude either way and
replayed from ``seeds`` seeds, the directions spread over worker processes. Each teacher's result is
kept in ``RUN_DIR/sensitivity/seed-S.json`` (:func:`~imitate.evaluation.sensitivity.result_path`)
with its model's SHA-256; a result of the same model, code and settings is reused. ``imitate compare
--similarity importance`` plans with them. :func:`report` is the table per teacher; :func:`predict`
sets the alignments beside a comparison's ``variance - uniform``.
"""

from __future__ import annotations

import hashlib
import json
import multiprocessing
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

from imitate.envs.task import Task, get_task
from imitate.errors import ImitateError
from imitate.evaluation import sensitivity as sens
from imitate.evaluation.replication import CONFIRMATION_SEED
from imitate.evaluation.teachers import MAX_TEACHERS, check_model, check_run, run_task, teachers
from imitate.figures.plots import figure_png
from imitate.motion.replay import planning_task
from imitate.rundir.artifacts import load_json, save_bytes, save_json
from imitate.rundir.lock import locked
from imitate.stages.files import ModelFile
from imitate.stages.progress import bar
from imitate.stages.provenance import code_digest

__all__ = ["FIGURE", "measure", "predict", "report"]

FIGURE = "sensitivity.png"  # in RUN_DIR/sensitivity/
MAX_SEEDS = 20  # replays of each moved plan, at most
MAX_WORKERS = 256
_worker: dict = {}


def measure(
    run_dir: Path, n_teachers: int = 1, confirm: int = 0, workers: int = 1,
    magnitudes: Sequence[float] = sens.MAGNITUDES, seeds: int = sens.SEEDS,
    progress: bool | None = None,
) -> dict[int, dict]:
    """Each teacher's result (see the module) by seed, measured where not kept; the figure
    ``RUN_DIR/sensitivity/sensitivity.png`` drawn. Holds the run's lock throughout.

    Raises:
        ImitateError: ``magnitudes`` not positive and increasing, ``seeds`` outside
            1..:data:`MAX_SEEDS`, teacher or worker counts out of range, or what
            :func:`~imitate.evaluation.teachers.teachers` refuses.
    """
    magnitudes = tuple(float(k) for k in magnitudes)
    if not magnitudes or magnitudes[0] <= 0 or any(b <= a for a, b in zip(
            magnitudes, magnitudes[1:], strict=False)) or not np.all(np.isfinite(magnitudes)):
        raise ImitateError(f"--magnitudes {','.join(map(str, magnitudes))} not accepted: "
                           "positive tolerances, increasing, e.g. 1,2,4")
    for name, value, low, high in (("--seeds", seeds, 1, MAX_SEEDS),
                                   ("--teachers", n_teachers, 1, MAX_TEACHERS),
                                   ("--confirm", confirm, 0, MAX_TEACHERS),
                                   ("--workers", workers, 1, MAX_WORKERS)):
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            raise ImitateError(f"{name} {value!r} not accepted: a whole number in {low}..{high}")
    run_dir = check_run(run_dir)
    task = get_task(run_task(run_dir))
    names = sens.direction_names(task)
    with locked(run_dir, f"imitate sensitivity {run_dir}"):
        check_model(run_dir)
        if ModelFile.load_learned(run_dir).frames:
            raise ImitateError(f"{run_dir} learned in TP-GMM's frames (--task-space tpgmm), "
                               "reproduced anew in each scene; sensitivity probes one space: "
                               "learn it with --task-space declared or auto")
        more = tuple(range(CONFIRMATION_SEED, CONFIRMATION_SEED + confirm))
        models = {t.seed: t for t in teachers(run_dir, run_dir / "eval", n_teachers, more,
                                              workers)}
        code = code_digest()
        keys = {s: hashlib.sha256(t.model_bytes + json.dumps([code, magnitudes, seeds]).encode())
                .hexdigest() for s, t in models.items()}
        results: dict[int, dict] = {}
        for s in models:
            path = sens.result_path(run_dir, s)
            try:
                kept = load_json(path) if path.exists() else None
            except ImitateError:  # cut short or corrupt: measured again
                kept = None
            if isinstance(kept, dict) and kept.get("key") == keys[s]:
                results[s] = kept
        jobs = [(s, i, magnitudes, seeds) for s in models if s not in results
                for i in range(len(names))]
        rates = {s: np.zeros((len(names), 2, len(magnitudes))) for s in models}
        done = dict.fromkeys(models, 0)
        learned = {s: t.learned for s, t in models.items()}
        sens.results_folder(run_dir).mkdir(exist_ok=True)
        if jobs:
            context = multiprocessing.get_context("spawn")
            with context.Pool(min(workers, len(jobs)), _start, (learned, task.name)) as pool:
                found = pool.imap_unordered(_probe, jobs)
                for seed, index, r in bar(found, progress, total=len(jobs), desc="sensitivity",
                                          unit="direction"):
                    rates[seed][index] = r
                    done[seed] += 1
                    if done[seed] == len(names):
                        results[seed] = {
                            "seed": seed, "key": keys[seed],
                            "model": sens.model_digest(models[seed].model_bytes),
                            "magnitudes": magnitudes,
                            **_summary(learned[seed], learned[seed].task(task), rates[seed],
                                       magnitudes),
                        }
                        save_json(sens.result_path(run_dir, seed), results[seed])
        save_bytes(sens.results_folder(run_dir) / FIGURE, figure_png(_plot(results, task.space.m)))
    return {s: results[s] for s in sorted(results)}


def _start(models: dict, task: str) -> None:
    _worker.update(models=models, task=get_task(task), plans={})


def _probe(job: tuple[int, int, tuple[float, ...], int]) -> tuple[int, int, list]:
    """One teacher's failure rates along one direction (in a worker)."""
    seed, index, magnitudes, seeds = job
    learned = _worker["models"][seed]
    task = learned.task(_worker["task"])
    if seed not in _worker["plans"]:
        plan = sens.reproduction(learned.model, learned.gaze, task)
        covariance = sens.critical_covariance(learned.model, plan, task)
        _worker["plans"][seed] = plan, sens.probe_directions(covariance)
    plan, directions = _worker["plans"][seed]
    task_map = planning_task(task.scene(), learned.gaze)
    rates = sens.failure_rates(plan, task_map, task, learned.gaze, directions[index],
                               magnitudes, seeds)
    return seed, index, rates.tolist()


def _summary(learned, task: Task, rates: np.ndarray, magnitudes) -> dict:
    """A teacher's result from its failure rates ``(2 m, 2, k)``."""
    plan = sens.reproduction(learned.model, learned.gaze, task)
    covariance = sens.critical_covariance(learned.model, plan, task)
    directions = sens.probe_directions(covariance)
    tolerances = np.array([sens.tolerance(r, magnitudes) for r in rates])
    importance = 1.0 / tolerances**2
    return {
        "directions": directions.tolist(),
        "variance_along": np.einsum("ij,jk,ik->i", directions, covariance, directions).tolist(),
        "rates": rates.tolist(),
        "tolerance": [t if np.isfinite(t) else None for t in tolerances],
        "quadratic_form": sens.quadratic_form(directions, importance).tolist(),
        "alignment": sens.alignment(covariance, importance),
    }


def report(results: dict[int, dict], task: Task, seeds: int) -> str:
    """Per teacher: each direction's tolerance, the demonstrations' variance along it and the
    two alignments (markdown)."""
    magnitudes = next(iter(results.values()))["magnitudes"]
    names = sens.direction_names(task)
    lines = [
        f"{task.name}: moves of {', '.join(f'{k:g}' for k in magnitudes)} tolerances either way "
        f"in the critical phase, {seeds} replays each; tolerance [tolerances] (variance along it "
        "[tolerances^2])", "",
        "| teacher | " + " | ".join(names) + " | alignment eigen | diagonal |",
        "|---" * (len(names) + 3) + "|",
    ]
    for s, r in results.items():
        cells = [f"{'>' + format(magnitudes[-1], 'g') if t is None else format(t, '.1f')} "
                 f"({v:.2f})" for t, v in zip(r["tolerance"], r["variance_along"], strict=True)]
        a = r["alignment"]
        lines.append(f"| {s} | " + " | ".join(cells)
                     + f" | {a['eigen']:+.2f} | {a['diagonal']:+.2f} |")
    eigen, diagonal = (np.array([r["alignment"][k] for r in results.values()])
                       for k in ("eigen", "diagonal"))
    lines += ["", f"alignment over {len(results)} teacher(s): eigen median "
              f"{np.nanmedian(eigen):+.2f}, {np.sum(eigen > 0)} above 0; diagonal median "
              f"{np.nanmedian(diagonal):+.2f}, {np.sum(diagonal < 0)} below 0"]
    return "\n".join(lines)


def predict(results: dict[int, dict], compared: dict) -> str:
    """Each alignment against the per-teacher success difference ``variance - uniform`` of a
    comparison's ``compare.json`` contents (markdown).

    Raises:
        ImitateError: a comparison without ``variance`` and ``uniform``, or of none of these
            teachers.
    """
    weightings = compared.get("weightings", {}) if isinstance(compared, dict) else {}
    if not {"variance", "uniform"} <= set(weightings):
        raise ImitateError("--against needs a compare.json of variance and uniform (imitate "
                           "compare RUN --similarity variance,uniform)")
    rates = {w: weightings[w]["by_teacher"] for w in ("variance", "uniform")}
    seeds = [s for s in results if str(s) in rates["variance"]]
    if not seeds:
        raise ImitateError("--against: the comparison has none of these teachers")
    difference = np.array([rates["variance"][str(s)]["success_rate"]
                           - rates["uniform"][str(s)]["success_rate"] for s in seeds])
    lines = [
        f"against {len(seeds)} teachers' variance - uniform (success; mean "
        f"{100 * difference.mean():+.1f} pp):", "",
        "| alignment | Spearman over teachers | sign predicted (alignment > 0 : eq. 21 wins) |",
        "|---|---|---|",
    ]
    for name in ("eigen", "diagonal"):
        index = np.array([results[s]["alignment"][name] for s in seeds])
        ok = np.isfinite(index) & (difference != 0)
        rho = spearmanr(index[ok], difference[ok])[0] if ok.sum() > 2 else float("nan")
        hits = int(np.sum(np.sign(index[ok]) == np.sign(difference[ok])))
        lines.append(f"| {name} | {rho:+.2f} | {hits} of {ok.sum()} (ties and NaN left out) |")
    return "\n".join(lines)


def _plot(results: dict[int, dict], m: int):
    """The demonstrations' precision against the measured importance, per direction of the
    ``m`` task dimensions and as many eigen-directions."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9, 4), layout="constrained")
    for ax, (name, rows) in zip(figure.subplots(1, 2),
                                (("task dimensions", slice(0, m)),
                                 ("eigen-directions", slice(m, 2 * m))), strict=True):
        for s, r in sorted(results.items()):
            variance = np.array(r["variance_along"])[rows]
            tol = np.array([np.nan if t is None else t for t in r["tolerance"]])[rows]
            ax.scatter(1.0 / variance, np.where(np.isfinite(tol), 1.0 / tol**2, 1e-2), s=12,
                       label=str(s))
        ax.set(xscale="log", yscale="log", title=name,
               xlabel="demonstrations' precision [1/tolerance^2]",
               ylabel="measured importance [1/tolerance^2] (never failed: 0.01)")
    if results:
        figure.axes[0].legend(title="teacher", fontsize=6, ncols=2)
    return figure
