"""Does the default scenario show the paper's Fig. 8-9 effect? One default run per seed, a table.

For each seed the default pipeline (``observe``, ``learn``, ``optimize``, ``replay``; the same
stages and settings as ``imitate run --seed N``, without the figures) runs in ``OUT/seedN`` and
one row is printed from its ``report.json``:

- ``w0 [mm]``: smallest signed distance of the plan without the collision cost (target <= -20),
- ``plan`` / ``phys [mm]``: the same at the default collision weight, planned and in the
  physics replay (targets >= 10),
- ``dev [mm]``: largest position change (dx, dy, dz) at the default weight from the weight-0
  reproduction (target >= 20),
- ``share``: share of the squared change in steps of above-median GMR variance (>= 0.8),
- ``pour [mm, deg]``: the critical phase's largest error from the GMR mean (<= 10 mm, <= 2 deg;
  headed by the phase's name: pour's pour phase),
- ``frac``: smallest score of the replays (the measure the task's success is judged by: pour's
  pour fraction; shown, not a target here: ``imitate eval`` measures it),
- ``outcome``: the run's (the task's own: ``success`` or why not; shown, not a target),

and a final line ``k of n seeds meet all targets; s succeed``.

Usage: ``python scripts/experiments/scenario_check.py [--task pour] [--seeds 20 21 ...]
[--out runs/scenario] [--from-stage optimize]`` (``--from-stage`` re-runs only the later stages on
existing run directories, e.g. to check a new optimizer setting on the same learned models;
``--collision-weight W`` instead of the default).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from imitate.envs import tasks
from imitate.envs.task import get_task
from imitate.evaluation.record import error_keys
from imitate.stages.config import RunConfig
from imitate.stages.runner import run_stage
from imitate.stages.table import NAMES

TARGETS = {
    "w0": lambda r: r["w0"] <= -20.0,
    "plan": lambda r: r["plan"] >= 10.0,
    "phys": lambda r: r["phys"] >= 10.0,
    "dev": lambda r: r["dev"] >= 20.0,
    "share": lambda r: r["share"] >= 0.8,
    "err_mm": lambda r: r["err_mm"] <= 10.0,
    "err_deg": lambda r: r["err_deg"] <= 2.0,
}


def check(seed: int, run_dir: Path, first: str, **settings) -> dict[str, float]:
    """Run the default pipeline from stage ``first`` for ``seed``; its numbers."""
    config = RunConfig(seed=seed, **settings)
    task = get_task(config.task)
    error_m, error_deg = error_keys(task)
    run_dir.mkdir(parents=True, exist_ok=True)
    for stage in NAMES[NAMES.index(first) : NAMES.index("replay") + 1]:
        report = run_stage(stage, run_dir, config, force=first != "observe")
    opt, replay = report["optimization"], report["replay"]
    sweep = {entry["weight"]: entry for entry in opt["sweep"]}
    chosen = sweep[opt["collision_weight"]]
    return {
        "w0": sweep[min(sweep)]["min_distance_m"] * 1e3,
        "plan": opt["min_distance_m"] * 1e3,
        "phys": replay["min_distance_m"] * 1e3,
        "dev": chosen["max_deviation_m"] * 1e3,
        "share": chosen["change_high_variance_share"],
        "err_mm": opt[error_m] * 1e3,
        "err_deg": opt[error_deg],
        "frac": min(replay[f"{task.score.measure}s"]),
        "outcome": replay["outcome"],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", choices=tasks.NAMES, default=tasks.DEFAULT)
    parser.add_argument("--seeds", type=int, nargs="+", default=list(range(20, 30)))
    parser.add_argument("--out", type=Path, default=Path("runs/scenario"))
    parser.add_argument("--from-stage", choices=NAMES[:4], default="observe")
    parser.add_argument("--collision-weight", type=float, help="instead of the default")
    args = parser.parse_args(argv)
    settings = {"task": args.task}
    if args.collision_weight is not None:
        settings["collision_weight"] = args.collision_weight
    phase = get_task(args.task).phase[:4]
    header = (
        f"{'seed':>4} {'w0 [mm]':>8} {'plan':>6} {'phys':>6} {'dev [mm]':>8} {'share':>6} "
        f"{phase + ' [mm':>8} {'deg]':>5} {'frac':>5} {'outcome':>12}  verdict"
    )
    print(header, flush=True)
    passed = successes = 0
    for seed in args.seeds:
        r = check(seed, args.out / f"seed{seed}", args.from_stage, **settings)
        successes += r["outcome"] == "success"
        failed = [name for name, ok in TARGETS.items() if not ok(r)]
        passed += not failed
        verdict = "ok" if not failed else "FAIL: " + ", ".join(failed)
        print(
            f"{seed:>4} {r['w0']:8.1f} {r['plan']:6.1f} {r['phys']:6.1f} {r['dev']:8.1f} "
            f"{r['share']:6.2f} {r['err_mm']:8.1f} {r['err_deg']:5.2f} {r['frac']:5.2f} "
            f"{r['outcome']:>12}  "
            f"{verdict}",
            flush=True,
        )
    print(f"{passed} of {len(args.seeds)} seeds meet all targets; {successes} succeed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
