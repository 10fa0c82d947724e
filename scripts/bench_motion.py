"""Benchmark of the movement optimization: total time and per-iteration breakdown.

Usage: ``python scripts/bench_motion.py [--repeats 3] [--max-iter 100]
[--collision-weight 3000]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from imitate.models import humanoid
from imitate.motion import PlanConfig, plan_from_model, setup
from imitate.motion.control import backward, rollout
from imitate.oracle import oracle_model
from imitate.replay import planning_task


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--max-iter", type=int, default=PlanConfig().max_iter)
    parser.add_argument("--collision-weight", type=float, default=PlanConfig().collision_weight)
    args = parser.parse_args()
    task = planning_task()
    learned = oracle_model(task.gaze)
    g = learned.gmm
    config = PlanConfig(collision_weight=args.collision_weight, max_iter=args.max_iter)
    print(
        f"movement {learned.times[-1]:.2f} s, dt {config.dt} s, K={g.n_components}, "
        f"collision weight {config.collision_weight}"
    )
    print("| run | total [s] | iterations | rollouts | per iteration [ms] | min distance [mm] |")
    print("|---|---|---|---|---|---|")
    for k in range(args.repeats):
        start = time.perf_counter()
        p = plan_from_model(task, learned, q0=humanoid.rest_pose(), config=config)
        total = time.perf_counter() - start
        print(f"| {k} | {total:.2f} | {p.n_iter} | {p.n_evaluations} | "
              f"{1000 * total / max(p.n_evaluations, 1):.1f} | {p.min_distance * 1000:.1f} |")

    # Breakdown of one iteration: forward rollout (with distances), cost terms, backward pass.
    problem = setup(task, learned, q0=humanoid.rest_pose(), config=config).problem
    distmax = problem.terms["collision"][1].distmax
    timings = {"rollout (kinematics, RMR)": [], "distances": [], "costs": [], "gradient": []}
    for _ in range(args.repeats):
        target = problem.dynamics.trajectory(p.attractors, problem.x_start)
        t0 = time.perf_counter()
        rollout(task, target, p.q_start, config.control, problem.limits)
        t1 = time.perf_counter()
        result = rollout(task, target, p.q_start, config.control, problem.limits, distmax)
        t2 = time.perf_counter()
        gq, gx = np.zeros_like(result.q), np.zeros_like(target)
        for weight, term in problem.terms.values():
            _, tq, tx = term(result, target)
            gq += weight * tq
            gx += weight * tx
        t3 = time.perf_counter()
        problem.dynamics.gradient(backward(result, task, config.control, gq, gx))
        t4 = time.perf_counter()
        for name, dt in zip(timings, (t1 - t0, t2 - t1 - (t1 - t0), t3 - t2, t4 - t3), strict=True):
            timings[name].append(dt)
    print(f"\nper iteration, {len(p.times) - 1} steps (median of {args.repeats}):")
    print("| part | ms | us per step |")
    print("|---|---|---|")
    for name, values in timings.items():
        ms = 1000 * float(np.median(values))
        print(f"| {name} | {ms:.1f} | {1000 * ms / (len(p.times) - 1):.0f} |")


if __name__ == "__main__":
    main()
