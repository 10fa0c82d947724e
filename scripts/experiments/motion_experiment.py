"""Paper Fig. 8-9 on the oracle learned model: a sweep of collision weights, the pour-phase task
error, where the deviation from the GMR mean falls, and (``--physics``) the replay in physics,
also over seeded variations of grasp heights and an obstacle.

Usage: ``python scripts/experiments/motion_experiment.py [--weights 0 1000 10000] [--physics]
[--variations 10]
[--out runs/motion]``; writes ``fig9.png`` and ``costs.png`` under ``--out``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from imitate.demos.oracle import oracle_model
from imitate.envs.assembly import GRASP_RANGE, Obstacle, SceneConfig
from imitate.envs.pour.env import PouringEnv
from imitate.figures import plots
from imitate.models import humanoid, objects
from imitate.models.scene import TABLE_HEIGHT
from imitate.motion import PlanConfig, plan_from_model
from imitate.motion.metrics import deviation, pour_phase_error
from imitate.motion.replay import planning_task, replay
from imitate.rundir.artifacts import save_bytes
from imitate.stages.optimize import _clearance


def run_plan(task, learned, weight: float, max_iter: int):
    config = PlanConfig(collision_weight=weight, max_iter=max_iter)
    start = time.perf_counter()
    result = plan_from_model(task, learned, q0=humanoid.rest_pose(), config=config)
    return result, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--weights", type=float, nargs="+", default=[0.0, 1000.0, 10000.0, 100000.0]
    )
    parser.add_argument("--max-iter", type=int, default=60)
    parser.add_argument("--physics", action="store_true")
    parser.add_argument("--variations", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("runs/motion"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    task = planning_task()
    learned = oracle_model(task.gaze)
    print(f"learned model: K={learned.gmm.n_components}, {len(learned.times)} GMR steps")
    plans = {}
    for weight in args.weights:
        p, seconds = run_plan(task, learned, weight, args.max_iter)
        plans[weight] = p
        pos, ang = pour_phase_error(p)
        print(
            f"w_coll={weight:7.1f}: min distance {p.min_distance * 1000:6.1f} mm {p.closest}, "
            f"pour-phase error {pos * 1000:5.1f} mm / {ang:4.2f} deg, {p.n_iter} iterations "
            f"in {seconds:.2f} s; {p.message}"
        )
    base = plans[args.weights[0]]
    for weight in args.weights[1:]:
        d = deviation(plans[weight], base)
        print(
            f"w_coll={weight:7.1f}: squared deviation from the GMR mean {d['deviation_m2']:.4f} "
            f"m^2 ({d['deviation_high_variance_share']:.0%} above the median variance); change "
            f"from w_coll={args.weights[0]}: {d['change_from_first_m2']:.4f} m^2 "
            f"({d['change_high_variance_share']:.0%} above the median variance)"
        )
    _figures(plans, task, args.out)

    if args.physics:
        weight = PlanConfig().collision_weight
        p = plans[weight] if weight in plans else run_plan(task, learned, weight, args.max_iter)[0]
        env = PouringEnv()
        r = replay(p, env)
        print(
            f"physics (w_coll={weight}): pour fraction {r.pour_fraction:.2f}, spilled "
            f"{r.spilled}, min distance {r.min_distance * 1000:.1f} mm, task position error "
            f"max {np.linalg.norm(r.task_error[:, :3], axis=1).max() * 1000:.1f} mm"
        )
    if args.variations:
        rng = np.random.default_rng(0)
        successes = 0
        for k in range(args.variations):
            grasp = {obj: float(rng.uniform(*GRASP_RANGE[obj])) for obj in GRASP_RANGE}
            obstacle = Obstacle("box", (float(rng.uniform(0.45, 0.6)), float(rng.uniform(
                -0.1, 0.1)), TABLE_HEIGHT + 0.05), (0.03, 0.03, 0.05))
            config = SceneConfig(
                obstacles=(obstacle,), bottle_grasp=grasp[objects.BOTTLE],
                glass_grasp=grasp[objects.GLASS],
            )
            vtask = planning_task(config)
            p, seconds = run_plan(vtask, learned, PlanConfig().collision_weight, args.max_iter)
            env = PouringEnv(obstacles=(obstacle,))
            r = replay(p, env, seed=k, options={f"{o}_grasp": h for o, h in grasp.items()})
            ok = r.is_success and r.min_distance >= 0
            successes += ok
            print(
                f"variation {k}: grasps {grasp}, obstacle at {obstacle.pos}: plan min "
                f"{p.min_distance * 1000:.1f} mm, physics min {r.min_distance * 1000:.1f} mm, "
                f"pour {r.pour_fraction:.2f}, {'success' if ok else 'failure'} ({seconds:.1f} s)"
            )
        print(f"success rate {successes}/{args.variations}")


def _figures(plans, task, out: Path) -> None:
    base = next(iter(plans.values()))
    sweep = {weight: p.x for weight, p in plans.items()}
    clearance = {weight: _clearance(task, p.q) for weight, p in plans.items()}
    save_bytes(out / "fig9.png", plots.figure_png(
        plots.plot_collision_sweep(base.times, base.mean, base.variance, sweep, clearance)
    ))
    save_bytes(out / "costs.png", plots.figure_png(
        plots.plot_costs({weight: p.costs["total"] for weight, p in plans.items()})
    ))


if __name__ == "__main__":
    main()
