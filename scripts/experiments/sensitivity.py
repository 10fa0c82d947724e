"""The task's measured tolerance per teacher, and whether the demonstrations point at it
(:mod:`imitate.evaluation.sensitivity`).

    python scripts/experiments/sensitivity.py [RUN_DIR] [--teachers 10] [--confirm 0]
        [--workers 2] [--magnitudes 1,2,4] [--seeds 3] [--against COMPARE_JSON]

For each teacher (the run's own and the next seeds, then ``--confirm`` teachers of seeds 1000 and
up, learned under ``RUN_DIR/eval/teachers/`` as ``imitate eval`` learns them), its default
reproduction is moved in the critical phase along 14 directions (the 7 task dimensions, the 7
eigen-directions of the demonstrations' covariance there) by each magnitude [tolerances] either
way and replayed from ``--seeds`` seeds. Each teacher's result is kept in
``RUN_DIR/sensitivity/seed-S.json`` with its model's SHA-256 (a run again reuses those of the
same model, code and settings; ``imitate compare --similarity importance`` plans with them); the
script prints per teacher each direction's tolerance, the demonstrations' variance along it and
the two alignments, and writes ``sensitivity.png``. With ``--against`` (a
``compare.json`` of ``variance`` and ``uniform``), it also prints the rank correlation over
teachers between each alignment and ``variance - uniform``'s success difference, and how often
the alignment's sign predicts the difference's.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import multiprocessing
import os
import sys
from pathlib import Path

import numpy as np
from scipy.stats import spearmanr

from imitate.envs.task import get_task
from imitate.evaluation import sensitivity as sens
from imitate.evaluation.replication import CONFIRMATION_SEED
from imitate.evaluation.teachers import run_task, teachers
from imitate.figures.plots import figure_png
from imitate.motion.replay import planning_task
from imitate.rundir.artifacts import save_bytes, save_json
from imitate.stages.provenance import code_digest

_worker: dict = {}


def _start(models: dict, task: str) -> None:
    _worker.update(models=models, task=get_task(task), plans={})


def _probe(job: tuple[int, int, tuple[float, ...], int]) -> tuple[int, int, list]:
    """One teacher's failure rates along one direction (in a worker)."""
    seed, index, magnitudes, seeds = job
    learned, task = _worker["models"][seed], _worker["task"]
    if seed not in _worker["plans"]:
        plan = sens.reproduction(learned.model, learned.gaze, task)
        covariance = sens.critical_covariance(learned.model, plan, task.critical(plan.mean))
        _worker["plans"][seed] = plan, sens.probe_directions(covariance)
    plan, directions = _worker["plans"][seed]
    task_map = planning_task(task.scene(), learned.gaze)
    rates = sens.failure_rates(plan, task_map, task, learned.gaze, directions[index],
                               magnitudes, seeds)
    return seed, index, rates.tolist()


def summary(learned, task, rates: np.ndarray, magnitudes) -> dict:
    """A teacher's JSON result from its failure rates ``(14, 2, k)``."""
    plan = sens.reproduction(learned.model, learned.gaze, task)
    covariance = sens.critical_covariance(learned.model, plan, task.critical(plan.mean))
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", nargs="?", default="runs/latest", type=Path)
    parser.add_argument("--teachers", type=int, default=10)
    parser.add_argument("--confirm", type=int, default=0)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--magnitudes", default=",".join(f"{k:g}" for k in sens.MAGNITUDES))
    parser.add_argument("--seeds", type=int, default=sens.SEEDS)
    parser.add_argument("--against", type=Path)
    args = parser.parse_args()
    magnitudes = tuple(sorted(float(k) for k in args.magnitudes.split(",")))
    task = get_task(run_task(args.run_dir))
    more = tuple(range(CONFIRMATION_SEED, CONFIRMATION_SEED + args.confirm))
    models = {t.seed: t for t in teachers(args.run_dir, args.run_dir / "eval", args.teachers,
                                          more, args.workers)}
    out = args.run_dir / "sensitivity"
    out.mkdir(exist_ok=True)
    code = code_digest()
    keys = {
        s: hashlib.sha256(t.model_bytes + json.dumps([code, magnitudes, args.seeds]).encode())
        .hexdigest() for s, t in models.items()
    }
    results: dict[int, dict] = {}
    for s in models:
        path = sens.result_path(args.run_dir, s)
        if path.exists() and (kept := json.loads(path.read_text())).get("key") == keys[s]:
            results[s] = kept
    jobs = [(s, i, magnitudes, args.seeds) for s in models if s not in results for i in range(14)]
    print(f"sensitivity: {len(models)} teachers ({len(results)} kept), {len(jobs)} directions "
          f"to probe, {len(magnitudes) * 2 * args.seeds} replays each at most", file=sys.stderr)
    rates = {s: np.zeros((14, 2, len(magnitudes))) for s in models}
    done = {s: 0 for s in models}
    context = multiprocessing.get_context("spawn")
    learned = {s: t.learned for s, t in models.items()}
    with context.Pool(args.workers, _start, (learned, task.name)) as pool:
        for seed, index, found in pool.imap_unordered(_probe, jobs):
            rates[seed][index] = found
            done[seed] += 1
            print(f"  teacher {seed}: {done[seed]}/14 directions", file=sys.stderr, flush=True)
            if done[seed] == 14:
                model = sens.model_digest(models[seed].model_bytes)
                results[seed] = {"seed": seed, "key": keys[seed], "model": model,
                                 "magnitudes": magnitudes,
                                 **summary(learned[seed], task, rates[seed], magnitudes)}
                save_json(sens.result_path(args.run_dir, seed), results[seed])
    report(results, task, magnitudes, args.seeds)
    save_bytes(out / "sensitivity.png", figure_png(plot(results)))
    if args.against:
        predict(results, json.loads(args.against.read_text()))


def report(results: dict[int, dict], task, magnitudes, seeds: int) -> None:
    """Per teacher: each direction's tolerance and the demonstrations' variance along it."""
    print(f"{task.name}: moves of {', '.join(f'{k:g}' for k in magnitudes)} tolerances either "
          f"way in the critical phase, {seeds} replays each; tolerance [tolerances] (variance "
          "along it [tolerances^2])\n")
    print("| teacher | " + " | ".join(sens.DIRECTION_NAMES) + " | alignment eigen | diagonal |")
    print("|---" * (len(sens.DIRECTION_NAMES) + 3) + "|")
    for s in sorted(results):
        r = results[s]
        cells = [f"{'>' + format(magnitudes[-1], 'g') if t is None else format(t, '.1f')} "
                 f"({v:.2f})" for t, v in zip(r["tolerance"], r["variance_along"], strict=True)]
        a = r["alignment"]
        print(f"| {s} | " + " | ".join(cells) + f" | {a['eigen']:+.2f} | {a['diagonal']:+.2f} |")


def predict(results: dict[int, dict], compared: dict) -> None:
    """Each alignment against the per-teacher success difference ``variance - uniform``."""
    rates = {w: compared["weightings"][w]["by_teacher"] for w in ("variance", "uniform")}
    seeds = [s for s in sorted(results) if str(s) in rates["variance"]]
    difference = np.array([rates["variance"][str(s)]["success_rate"]
                           - rates["uniform"][str(s)]["success_rate"] for s in seeds])
    print(f"\nagainst {len(seeds)} teachers' variance - uniform (success; mean "
          f"{100 * difference.mean():+.1f} pp):\n")
    print("| alignment | Spearman over teachers | sign predicted (alignment > 0 : eq. 21 wins) |")
    print("|---|---|---|")
    for name in ("eigen", "diagonal"):
        index = np.array([results[s]["alignment"][name] for s in seeds])
        ok = np.isfinite(index) & (difference != 0)
        rho = spearmanr(index[ok], difference[ok])[0] if ok.sum() > 2 else float("nan")
        hits = int(np.sum(np.sign(index[ok]) == np.sign(difference[ok])))
        print(f"| {name} | {rho:+.2f} | {hits} of {ok.sum()} (ties and NaN left out) |")


def plot(results: dict[int, dict]):
    """The demonstrations' precision against the measured importance, per direction."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(9, 4), layout="constrained")
    for ax, (name, rows) in zip(figure.subplots(1, 2),
                                (("task dimensions", slice(0, 7)),
                                 ("eigen-directions", slice(7, 14))), strict=True):
        for s, r in sorted(results.items()):
            variance = np.array(r["variance_along"])[rows]
            tol = np.array([np.nan if t is None else t for t in r["tolerance"]])[rows]
            ax.scatter(1.0 / variance, np.where(np.isfinite(tol), 1.0 / tol**2, 1e-2), s=12,
                       label=str(s))
        ax.set(xscale="log", yscale="log", title=name,
               xlabel="demonstrations' precision [1/tolerance^2]",
               ylabel="measured importance [1/tolerance^2] (never failed: 0.01)")
    figure.axes[0].legend(title="teacher", fontsize=6, ncols=2)
    return figure


if __name__ == "__main__":
    main()
