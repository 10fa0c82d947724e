"""Benchmark of the movement optimization: total time and per-iteration breakdown, this tree's
planner beside an earlier commit's on the same problem.

Usage: ``python scripts/bench/bench_motion.py [--repeats 3] [--max-iter 100]
[--collision-weight 10000] [--baseline 8a4964a]``.

The problem is the oracle model's 5 s movement with the paper's attractors (K, one per GMM
component: the baseline's; ``PlanConfig.attractor_spacing=None`` here), learned once here and
handed to both planners as arrays. The baseline's ``imitate`` is exported with
``git archive`` into a temporary directory and run from there; the two run in alternation, each
in its own process, ``--repeats`` plans per process after one untimed plan (numba's kernels
compiled or loaded). Each row gives the wall time, the processor time of the plan (robust to a
shared machine; the load average is printed with it), iterations, the best total cost and the
clearance; the summary compares the medians and the optima (cost within 1 %, clearance within
1 mm). ``--baseline ''`` runs this tree alone.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
# The planner before issue 16 (the speed work): the tree this branch started from.
BASELINE = "8a4964a"


def child(model_path: Path, repeats: int, max_iter: int, weight: float) -> dict:
    """Plans ``repeats`` times with the ``imitate`` on ``sys.path``; returns the timings."""
    from imitate.learning import LearnedModel
    from imitate.models import humanoid
    from imitate.motion import PlanConfig, plan_from_model, setup
    from imitate.motion.control import backward, rollout
    from imitate.motion.replay import planning_task

    arrays = dict(np.load(model_path))
    task = planning_task(gaze=arrays.pop("gaze"))
    learned = LearnedModel.from_arrays(arrays)
    # the baseline's problem: one attractor per GMM component (its only kind)
    fields = PlanConfig.__dataclass_fields__
    paper = {"attractor_spacing": None} if "attractor_spacing" in fields else {}
    config = PlanConfig(collision_weight=weight, max_iter=max_iter, **paper)
    q0 = humanoid.rest_pose()
    plan_from_model(task, learned, q0=q0, config=config)  # untimed: kernels compiled or loaded
    runs = []
    for _ in range(repeats):
        wall, cpu = time.perf_counter(), time.process_time()
        p = plan_from_model(task, learned, q0=q0, config=config)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        runs.append({
            "wall": wall, "cpu": cpu, "iterations": p.n_iter, "evaluations": p.n_evaluations,
            "cost": float(np.min(p.costs["total"])), "min_distance": p.min_distance,
            "load": os.getloadavg()[0],
        })
    # Breakdown of one iteration [thread CPU]: forward rollout without and with distances,
    # the cost terms, the backward pass.
    problem = setup(task, learned, q0=q0, config=config).problem
    distmax = problem.terms["collision"][1].distmax
    target = problem.dynamics.trajectory(p.attractors, problem.x_start)
    parts = {"rollout (kinematics, RMR)": [], "distances": [], "costs": [], "gradient": []}
    clock = time.thread_time
    for _ in range(max(repeats, 5)):
        t0 = clock()
        rollout(task, target, p.q_start, config.control, problem.limits)
        t1 = clock()
        result = rollout(task, target, p.q_start, config.control, problem.limits, distmax)
        t2 = clock()
        gq, gx = np.zeros_like(result.q), np.zeros_like(target)
        for w, term in problem.terms.values():
            _, tq, tx = term(result, target)
            gq += w * tq
            gx += w * tx
        t3 = clock()
        problem.dynamics.gradient(backward(result, task, config.control, gq, gx))
        t4 = clock()
        for name, dt in zip(parts, (t1 - t0, t2 - t1 - (t1 - t0), t3 - t2, t4 - t3),
                            strict=True):
            parts[name].append(dt)
    return {
        "runs": runs,
        "steps": len(p.times) - 1,
        "components": int(learned.gmm.n_components),
        "parts": {name: float(np.median(v)) for name, v in parts.items()},
    }


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


def run_child(label: str, path: Path | None, args, model: Path) -> dict:
    env = dict(os.environ)
    if path is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(path), env.get("PYTHONPATH", "")])
    command = [
        sys.executable, __file__, "--child", str(model), "--repeats", str(args.repeats),
        "--max-iter", str(args.max_iter), "--collision-weight", str(args.collision_weight),
    ]
    out = subprocess.run(command, env=env, check=True, capture_output=True, text=True).stdout
    result = json.loads(out.strip().splitlines()[-1])
    result["label"] = label
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--max-iter", type=int, default=100)
    parser.add_argument("--collision-weight", type=float, default=10000.0)
    parser.add_argument("--baseline", default=BASELINE,
                        help=f"commit to compare with (default {BASELINE}); '' for none")
    parser.add_argument("--rounds", type=int, default=2, help="alternations of the two")
    parser.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child:
        print(json.dumps(child(args.child, args.repeats, args.max_iter, args.collision_weight)))
        return

    from imitate.demos.oracle import oracle_model
    from imitate.motion.replay import planning_task

    with tempfile.TemporaryDirectory(prefix="bench_motion-") as name:
        tmp = Path(name)
        gaze = planning_task().gaze
        model = tmp / "model.npz"
        np.savez(model, gaze=gaze, **oracle_model(gaze).to_arrays())
        versions = [("this tree", None)]
        if args.baseline:
            base = export(args.baseline, tmp / "baseline")
            versions.insert(0, (f"baseline {args.baseline}", base))
        results = {label: [] for label, _ in versions}
        for _ in range(args.rounds):
            for label, path in versions:
                results[label].append(run_child(label, path, args, model))
    first = next(iter(results.values()))[0]
    print(f"movement 5 s, {first['steps']} steps, K={first['components']}, collision weight "
          f"{args.collision_weight:g}; {os.cpu_count()} cores")
    print("| planner | run | wall [s] | CPU [s] | iterations | rollouts | CPU per iteration [ms] "
          "| best cost | min distance [mm] | load |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    summary = {}
    for label, rounds in results.items():
        runs = [run for r in rounds for run in r["runs"]]
        for k, run in enumerate(runs):
            print(f"| {label} | {k} | {run['wall']:.3f} | {run['cpu']:.3f} | {run['iterations']} "
                  f"| {run['evaluations']} | {1000 * run['cpu'] / run['evaluations']:.1f} "
                  f"| {run['cost']:.4f} | {1000 * run['min_distance']:.2f} | {run['load']:.2f} |")
        summary[label] = {
            key: float(np.median([run[key] for run in runs]))
            for key in ("wall", "cpu", "cost", "min_distance")
        }
        summary[label]["parts"] = {
            name: float(np.median([r["parts"][name] for r in rounds])) for name in first["parts"]
        }
    print(f"\nper iteration, {first['steps']} steps, processor time [ms] (median):")
    print("| part | " + " | ".join(results) + " |")
    print("|---|" + "---|" * len(results))
    for name in first["parts"]:
        print(f"| {name} | "
              + " | ".join(f"{1000 * summary[label]['parts'][name]:.2f}" for label in results)
              + " |")
    if len(results) == 2:
        (old_label, old), (new_label, new) = summary.items()
        cost = 100 * (new["cost"] - old["cost"]) / old["cost"]
        clearance = 1000 * (new["min_distance"] - old["min_distance"])
        print(f"\n{new_label} / {old_label} (medians): CPU {new['cpu'] / old['cpu']:.2f}, wall "
              f"{new['wall'] / old['wall']:.2f}; best cost {cost:+.4f} %, clearance "
              f"{clearance:+.4f} mm")


if __name__ == "__main__":
    main()
