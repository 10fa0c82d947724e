"""Core-seconds of a comparison's variations and of learning one teacher, split into their
parts, for this tree and for other commits side by side in one run.

    python scripts/bench/bench_compare.py [RUN_DIR] [--suite effort] [--teachers 2] [--n 20]
        [--similarity variance,uniform] [--revision REV ...] [--learn]

For each tree (the working tree first, then each ``--revision``, exported from git as an
installed package, see :func:`export`) a child process runs the variations ``0..n-1`` of the
suite (drawn with seed 0) with each weighting and each teacher's learned model, one after the
other in its main thread, as a worker of ``imitate compare`` does, and measures each part in
processor time of that thread (a loaded machine slows it less than the wall clock):

- scene: the planning model and the physics env of the variation (MuJoCo models built);
- planning: the optimizer (:func:`~imitate.motion.optimizer.plan_from_model`);
- physics: MuJoCo's steps of the replays;
- replay, Python: the rest of the replays (actions, clearance, the task's measures, watcher);
- outcome, records: the rest of a variation (its task change, Mahalanobis distance, record).

The teachers' models are read from ``RUN_DIR`` and ``RUN_DIR/eval/teachers/seed-S`` (learn them
first with ``imitate eval RUN_DIR --teachers N --n 1``), so every tree plans the same models.
Prints the parts per variation, the ratio of each tree's total to the first's and whether each
variation's outcome (and its score, within ``--tolerance``) is the same as in the first tree.
With ``--learn``, each tree also learns one new teacher (seed 1000, the run's settings) in a
temporary folder: the observe stage's rendering and tracking, then learn.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PARTS = ("scene", "planning", "physics", "replay, Python", "outcome, records")


def export(revision: str, into: Path) -> Path:
    """``imitate`` of ``revision`` as an importable package under ``into`` (its ``envs/`` and
    ``models/`` moved inside, as the wheel installs them)."""
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", revision, "imitate", "envs", "models"],
        check=True, capture_output=True,
    ).stdout
    into.mkdir(parents=True)
    subprocess.run(["tar", "-x", "-C", str(into)], input=archive, check=True)
    for name in ("envs", "models"):
        shutil.move(str(into / name), str(into / "imitate" / name))
    return into


class Clock:
    """Processor time of this thread by part, with nesting: a part's time excludes the parts
    measured inside it."""

    def __init__(self):
        self.total: dict[str, float] = defaultdict(float)
        self._stack: list[list] = []

    def wrap(self, owner, name: str, part: str) -> None:
        """``owner.name`` (a function of a module or class) measured as ``part``; nothing if
        this tree has no such function."""
        inner = getattr(owner, name, None)
        if inner is None:
            return

        def timed(*args, **kwargs):
            self._stack.append([part, time.thread_time(), 0.0])
            try:
                return inner(*args, **kwargs)
            finally:
                part_, start, nested = self._stack.pop()
                spent = time.thread_time() - start
                self.total[part_] += spent - nested
                if self._stack:
                    self._stack[-1][2] += spent

        setattr(owner, name, timed)


def child(args) -> dict:
    """The variations of this tree's ``imitate``, timed by part (see the module)."""
    import imitate
    from imitate.envs.bimanual import BimanualEnv
    from imitate.envs.task import get_task
    from imitate.evaluation import trial as trial_module
    from imitate.evaluation.record import score_keys
    from imitate.evaluation.suite import named_suite
    from imitate.evaluation.suite_run import draw_jobs
    from imitate.evaluation.teachers import _read, teacher_seeds
    from imitate.evaluation.variation import Variation
    from imitate.stages.config import load_config

    run = Path(args.run)
    config = load_config(run)
    task = get_task(config.task)
    seeds = teacher_seeds(config.seed, args.teachers)
    folders = [run, *(run / "eval" / "teachers" / f"seed-{s}" for s in seeds[1:])]
    missing = [str(f) for f in folders if not (f / "model.npz").is_file()]
    if missing:
        sys.exit(f"no learned teacher in {missing[0]}: imitate eval {run} --teachers "
                 f"{args.teachers} --n 1 learns them")
    models = [_read(s, f / "model.npz") for s, f in zip(seeds, folders, strict=True)]
    _, suite = named_suite(args.suite, task)
    score = score_keys(task)[1]  # each variation's worst replay
    drawn = draw_jobs(models, suite, 0, args.n)

    clock = Clock()
    clock.wrap(Variation, "planning_task", "scene")
    clock.wrap(trial_module, "physics", "scene")
    clock.wrap(trial_module, "plan_from_model", "planning")
    clock.wrap(trial_module, "replay_once", "replay, Python")
    clock.wrap(BimanualEnv, "_simulate", "physics")
    clock.wrap(trial_module.Trial, "run", "outcome, records")
    trials = {m.seed: trial_module.Trial(m.learned, task) for m in models}
    for similarity in args.similarity.split(","):  # the free plans: once per teacher
        for d in drawn:
            trials[d.teacher].free(similarity, suite["max_iter"])
    outcomes = {}
    start, wall = time.thread_time(), time.perf_counter()
    for similarity in args.similarity.split(","):
        for d in drawn:
            for drawn_variation in d.variations:
                plan = drawn_variation.plan.replace(similarity=similarity)
                record = trials[d.teacher].run(dataclasses.replace(drawn_variation, plan=plan))
                key = f"{similarity} {d.teacher} {drawn_variation.id}"
                outcomes[key] = (record["outcome"], record[score])
    count = len(outcomes)
    result = {
        "imitate": imitate.__file__, "variations": count,
        "seconds": (time.thread_time() - start) / count,
        "wall": (time.perf_counter() - wall) / count,
        "parts": {p: clock.total[p] / count for p in PARTS},
        "outcomes": outcomes,
    }
    if args.learn:
        result["learn"] = learn_one(run)
    return result


def learn_one(run: Path) -> dict:
    """Seconds of learning a new teacher (seed 1000) with the run's settings: observe's
    rendering and tracking (its report's rates), observe in all and learn, each wall time."""
    from imitate.stages.config import load_config
    from imitate.stages.runner import run_stage

    config = dataclasses.replace(load_config(run), seed=1000)
    with tempfile.TemporaryDirectory() as folder:
        seconds = {}
        for stage in ("observe", "learn"):
            start = time.perf_counter()
            report = run_stage(stage, Path(folder), config)
            seconds[stage] = time.perf_counter() - start
        perception = report["perception"]
    return {**seconds, **{k: perception[k] for k in ("render_pairs_per_s", "track_pairs_per_s")}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run", nargs="?", default="runs/latest")
    parser.add_argument("--suite", default="effort")
    parser.add_argument("--teachers", type=int, default=2)
    parser.add_argument("--n", type=int, default=20)
    parser.add_argument("--similarity", default="variance,uniform")
    parser.add_argument("--revision", action="append", default=[],
                        help="another commit to measure beside the working tree")
    parser.add_argument("--learn", action="store_true", help="also learn one teacher")
    parser.add_argument("--tolerance", type=float, default=0.05,
                        help="largest difference of a variation's score counted as the same")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(child(args)))
        return
    results = []
    with tempfile.TemporaryDirectory() as scratch:
        trees = [("working tree", None)] + [
            (rev, export(rev, Path(scratch, f"tree{i}"))) for i, rev in enumerate(args.revision)
        ]
        for label, path in trees:
            env = dict(os.environ)
            if path is not None:
                env["PYTHONPATH"] = os.pathsep.join([str(path), env.get("PYTHONPATH", "")])
            cwd = scratch if path else None  # the working tree's own checkout, else none
            subprocess.run([sys.executable, "-m", "imitate.warmup"], env=env, cwd=cwd,
                           check=True, capture_output=True)  # no compiling in the measurement
            command = [
                sys.executable, __file__, "--child", str(Path(args.run).resolve()),
                "--suite", args.suite, "--teachers", str(args.teachers), "--n", str(args.n),
                "--similarity", args.similarity, *(["--learn"] if args.learn else []),
            ]
            print(f"{label}: {args.n} variations x {args.teachers} teachers x "
                  f"{len(args.similarity.split(','))} weightings ...", flush=True)
            out = subprocess.run(command, env=env, cwd=cwd, check=True,
                                 stdout=subprocess.PIPE, text=True).stdout
            results.append((label, json.loads(out.strip().splitlines()[-1])))
    report(results, args)


def report(results: list[tuple[str, dict]], args) -> None:
    """The table of parts per tree, the ratios and the outcomes' agreement."""
    load = os.getloadavg()
    print(f"\nmachine: {os.cpu_count()} cores, load average {load[0]:.2f}; suite {args.suite}, "
          f"core-seconds per variation (processor time of the worker's thread)")
    header = f"{'tree':28s}" + "".join(f"{p:>17s}" for p in PARTS) + f"{'total':>9s}{'ratio':>7s}"
    print(header)
    first = results[0][1]
    for label, r in results:
        parts = "".join(f"{r['parts'][p]:17.3f}" for p in PARTS)
        print(f"{label[:28]:28s}{parts}{r['seconds']:9.3f}{r['seconds'] / first['seconds']:7.2f}")
    for label, r in results:
        print(f"  {label}: {r['imitate']}")
    for label, r in results[1:]:
        same = close = 0
        differ = []
        for key, (outcome, score) in first["outcomes"].items():
            other, other_score = r["outcomes"].get(key, (None, None))
            if other == outcome:
                same += 1
                close += score is None or abs(score - other_score) <= args.tolerance
            else:
                differ.append(f"{key}: {outcome} / {other}")
        print(f"outcomes, {label} against the working tree: {same} of {len(first['outcomes'])} "
              f"the same, {close} with the score within {args.tolerance}")
        for line in differ[:10]:
            print(f"  differs: {line}")
    if "learn" in first:
        print(f"\n{'learning one teacher [s]':28s}{'observe':>10s}{'learn':>8s}"
              f"{'render pairs/s':>16s}{'track pairs/s':>15s}")
        for label, r in results:
            x = r["learn"]
            print(f"{label[:28]:28s}{x['observe']:10.1f}{x['learn']:8.1f}"
                  f"{x['render_pairs_per_s']:16.1f}{x['track_pairs_per_s']:15.1f}")


if __name__ == "__main__":
    main()
