"""Paper Fig. 8-9 on the oracle learned model: a sweep of collision weights, the task error in the
task's critical phase (pour: the pour phase), where the deviation from the GMR mean falls, and
(``--physics``) the replay in physics, also over seeded variations of grasp heights and an
obstacle.

Usage: ``python scripts/experiments/motion_experiment.py [--task pour] [--weights 0 1000 10000]
[--physics] [--variations 10] [--out runs/motion]``; writes ``fig9.png`` and ``costs.png`` under
``--out``.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from imitate.demos.oracle import oracle_model
from imitate.envs import tasks
from imitate.envs.assembly import Obstacle
from imitate.envs.task import get_task
from imitate.envs.teacher_motion import TeacherConfig
from imitate.figures import plots
from imitate.models import humanoid
from imitate.models.scene import TABLE_HEIGHT
from imitate.motion import PlanConfig, plan_from_model
from imitate.motion.metrics import critical_error, deviation
from imitate.motion.replay import measure, planning_task
from imitate.rundir.artifacts import save_bytes
from imitate.stages.optimize import _clearance


def run_plan(planning, learned, weight: float, max_iter: int, critical):
    config = PlanConfig(collision_weight=weight, max_iter=max_iter)
    start = time.perf_counter()
    result = plan_from_model(
        planning, learned, q0=humanoid.rest_pose(), config=config, critical=critical
    )
    return result, time.perf_counter() - start


def measures(record: dict) -> str:
    """A replay's task measures (``Task.record``) as text."""
    return ", ".join(
        f"{key} {value:.2f}" if isinstance(value, float) else f"{key} {value}"
        for key, value in record.items()
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", choices=tasks.NAMES, default=tasks.DEFAULT)
    parser.add_argument(
        "--weights", type=float, nargs="+", default=[0.0, 1000.0, 10000.0, 100000.0]
    )
    parser.add_argument("--max-iter", type=int, default=60)
    parser.add_argument("--physics", action="store_true")
    parser.add_argument("--variations", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("runs/motion"))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    task = get_task(args.task)
    planning = planning_task(task.scene())
    learned = oracle_model(planning.gaze, TeacherConfig(task=task.name))
    print(f"learned model: K={learned.gmm.n_components}, {len(learned.times)} GMR steps")
    plans = {}
    for weight in args.weights:
        p, seconds = run_plan(planning, learned, weight, args.max_iter, task.critical)
        plans[weight] = p
        pos, ang = critical_error(p, task.space, task.critical(p.mean))
        print(
            f"w_coll={weight:7.1f}: min distance {p.min_distance * 1000:6.1f} mm {p.closest}, "
            f"{task.phase}-phase error {pos * 1000:5.1f} mm / {ang:4.2f} deg, {p.n_iter} "
            f"iterations in {seconds:.2f} s; {p.message}"
        )
    base = plans[args.weights[0]]
    for weight in args.weights[1:]:
        d = deviation(plans[weight], base, task.space)
        print(
            f"w_coll={weight:7.1f}: squared deviation from the GMR mean {d['deviation_m2']:.4f} "
            f"m^2 ({d['deviation_high_variance_share']:.0%} above the median variance); change "
            f"from w_coll={args.weights[0]}: {d['change_from_first_m2']:.4f} m^2 "
            f"({d['change_high_variance_share']:.0%} above the median variance)"
        )
    _figures(plans, planning, args.out)

    if args.physics:
        weight = PlanConfig().collision_weight
        p = plans[weight] if weight in plans else run_plan(
            planning, learned, weight, args.max_iter, task.critical)[0]
        r = measure(task, p, task.make_env(task.scene()), seed=0, gaze=planning.gaze,
                    options=task.settings())[0]
        print(
            f"physics (w_coll={weight}): {measures(task.record(r.info))}, min distance "
            f"{r.min_distance * 1000:.1f} mm, task position error max "
            f"{np.linalg.norm(r.task_error[:, :3], axis=1).max() * 1000:.1f} mm"
        )
    if args.variations:
        rng = np.random.default_rng(0)
        successes = 0
        for k in range(args.variations):
            options = [task.options[f"{obj}_grasp"] for obj in task.objects]
            grasp = {
                f"{obj}_grasp": float(rng.uniform(o.low, o.high))
                for obj, o in zip(task.objects, options, strict=True)
            }
            obstacle = Obstacle("box", (float(rng.uniform(0.45, 0.6)), float(rng.uniform(
                -0.1, 0.1)), TABLE_HEIGHT + 0.05), (0.03, 0.03, 0.05))
            scene = task.scene(grasp, (obstacle,))
            vplanning = planning_task(scene)
            p, seconds = run_plan(
                vplanning, learned, PlanConfig().collision_weight, args.max_iter, task.critical
            )
            r = measure(task, p, task.make_env(scene), seed=k, gaze=vplanning.gaze,
                        options=grasp)[0]
            ok = r.info["is_success"] and r.min_distance >= 0
            successes += ok
            print(
                f"variation {k}: grasps {grasp}, obstacle at {obstacle.pos}: plan min "
                f"{p.min_distance * 1000:.1f} mm, physics min {r.min_distance * 1000:.1f} mm, "
                f"{measures(task.record(r.info))}, {'success' if ok else 'failure'} "
                f"({seconds:.1f} s)"
            )
        print(f"success rate {successes}/{args.variations}")


def _figures(plans, planning, out: Path) -> None:
    base = next(iter(plans.values()))
    sweep = {weight: p.x for weight, p in plans.items()}
    clearance = {weight: _clearance(planning, p.q) for weight, p in plans.items()}
    save_bytes(out / "fig9.png", plots.figure_png(
        plots.plot_collision_sweep(base.times, base.mean, base.variance, sweep, clearance)
    ))
    save_bytes(out / "costs.png", plots.figure_png(
        plots.plot_costs({weight: p.costs["total"] for weight, p in plans.items()})
    ))


if __name__ == "__main__":
    main()
