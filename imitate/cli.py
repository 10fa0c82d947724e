"""The ``imitate`` command: one sub-command per stage of a run, and ``run`` for all of them.

    imitate run --out runs/latest             # watch, learn, optimise, pour, plot
    imitate run --quick --out runs/quick      # small images, 3 demonstrations: under a minute
    imitate optimize runs/latest --collision-weight 30   # re-plan with the learned model
    imitate replay runs/latest && imitate figures runs/latest

Each stage reads the previous stage's artifacts in the run directory (see
:mod:`imitate.pipeline`); settings given on the command line replace those in its
``config.json``, the rest are kept.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from imitate.errors import ImitateError

__all__ = ["main"]

DEFAULT_RUN = Path("runs/latest")
HELP = {
    "observe": "the teacher demonstrates; track the objects in the robot's eyes; cut the demos",
    "learn": "task space, DTW, GMM (components by BIC), GMR mean and variance",
    "optimize": "whole-body attractor optimisation of the reproduction, Fig. 9 sweep",
    "replay": "the optimised movement in full physics: pour fraction, spill, clearance",
    "figures": "figures/*.png and video.mp4 from the run's artifacts",
    "run": "all stages: observe, learn, optimize, replay, figures",
}
# The settings each stage owns: (flag, RunConfig field, type, help); tests check the defaults.
KNOBS = {
    "observe": (
        ("--demos", "n_demos", int, "demonstrations the teacher shows, 2..20 (default 5)"),
        ("--width", "width", int, "head-camera image width [px], 64..1920 (default 640)"),
        ("--height", "height", int, "head-camera image height [px], 48..1080 (default 480)"),
        ("--fps", "fps", float, "camera rate [Hz], 5..120 (default 30)"),
    ),
    "learn": (
        ("--k-max", "k_max", int, "largest number of GMM components tried, 1..50 (default 30)"),
        ("--smoothing", "smoothing", float,
         "Savitzky-Golay window over the tracks before learning [s], 0..1 (default 0.3)"),
    ),
    "optimize": (
        ("--collision-weight", "collision_weight", float,
         "weight of the collision cost, >= 0 (default 3000)"),
        ("--max-iter", "max_iter", int, "optimiser iteration limit, >= 1 (default 100)"),
        ("--bottle-grasp", "bottle_grasp", float,
         "where the robot holds the bottle, height above its bottom [m] (default 0.09)"),
        ("--glass-grasp", "glass_grasp", float,
         "where the robot holds the glass, height above its bottom [m] (default 0.05)"),
    ),
    "replay": (
        ("--particles", "particles", int, "liquid spheres in the bottle, 1..120 (default 60)"),
    ),
    "figures": (
        ("--video-width", "video_width", int, "video width [px], 64..1920 (default 640)"),
        ("--video-height", "video_height", int, "video height [px], 48..1080 (default 480)"),
    ),
}
STAGE_ORDER = tuple(KNOBS)


def obstacle(text: str):
    """``--obstacle`` value: ``box:X,Y,Z:SX,SY,SZ`` (centre, half extents [m]),
    ``cylinder:X,Y,Z:R,H`` (centre, radius, half height [m]) or ``none``."""
    if text.lower() == "none":
        return None
    try:
        shape, pos, size = text.split(":")
        values = {
            "shape": shape,
            "pos": tuple(float(v) for v in pos.split(",")),
            "size": tuple(float(v) for v in size.split(",")),
        }
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} not accepted: box:X,Y,Z:SX,SY,SZ or cylinder:X,Y,Z:R,H [m] or none, e.g. "
            "box:0.55,0.0,0.70:0.03,0.03,0.05"
        ) from None
    from imitate.envs.assembly import Obstacle

    try:
        return Obstacle(**values)
    except ImitateError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="imitate",
        description="Task-level imitation learning of pouring (Muehlig et al., ICRA 2009), "
        "end to end in MuJoCo.",
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command, text in HELP.items():
        sub = commands.add_parser(command, help=text, description=text)
        sub.add_argument("run_dir", nargs="?", type=Path, metavar="RUN_DIR",
                         help=f"run directory (default {DEFAULT_RUN}); same as --out")
        sub.add_argument("--out", type=Path, metavar="DIR", help="run directory")
        sub.add_argument("--seed", type=int, metavar="N", help="seed of the whole run (default 0)")
        sub.add_argument("--quick", action="store_true",
                         help="small images, 3 demonstrations, short optimisation (tests)")
        stages = STAGE_ORDER if command == "run" else (command,)
        for stage in stages:
            group = sub.add_argument_group(f"{stage} settings")
            for flag, dest, kind, knob_help in KNOBS[stage]:
                group.add_argument(flag, dest=dest, type=kind, help=knob_help,
                                   metavar=kind.__name__.upper())
            if stage == "learn":
                group.add_argument("--bic", choices=("full", "fast"),
                                   help="choose the number of components by the full BIC (EM "
                                   "for every K) or the paper's fast K-means heuristic "
                                   "(default full)")
                group.add_argument("--oracle", action=argparse.BooleanOptionalAction,
                                   help="learn from ground-truth poses instead of perception "
                                   "(default --no-oracle)")
            if stage == "optimize":
                group.add_argument("--obstacle", type=obstacle, default=argparse.SUPPRESS,
                                   metavar="SHAPE:POS:SIZE",
                                   help=obstacle.__doc__.split(": ", 1)[1].replace("``", ""))
    return parser



def config_for(args: argparse.Namespace, run_dir: Path):
    """The run's configuration: ``config.json`` of ``run_dir`` for a later stage (a new one
    for ``run`` and ``observe``), with ``--quick`` and the given settings applied."""
    from imitate import pipeline

    stages = STAGE_ORDER if args.command == "run" else (args.command,)
    owned = {dest for stage in stages for _, dest, _, _ in KNOBS[stage]}
    owned |= {"oracle", "bic"} if "learn" in stages else set()
    given = {k: v for k, v in vars(args).items() if k in owned and v is not None}
    if "obstacle" in vars(args):  # given, possibly as "none"
        given["obstacle"] = args.obstacle
    if args.seed is not None:
        given["seed"] = args.seed
    fresh = args.command in ("run", "observe")
    base = pipeline.RunConfig() if fresh else pipeline.load_config(run_dir)
    if args.quick:
        quick = pipeline.RunConfig.quick().to_json()
        base = pipeline.RunConfig.from_json(
            {**base.to_json(), **{k: v for k, v in quick.items() if fresh or k in owned}}
        )
    return pipeline.RunConfig.from_json({**base.to_json(), **given})


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.run_dir and args.out and args.run_dir != args.out:
        parser.error(f"two run directories given: {args.run_dir} and --out {args.out}; give one")
    run_dir = args.out or args.run_dir or DEFAULT_RUN
    from imitate import pipeline  # heavy (MuJoCo, numba): only once the arguments are fine

    try:
        config = config_for(args, run_dir)
    except ImitateError as err:
        parser.error(str(err))
    stages = STAGE_ORDER if args.command == "run" else (args.command,)
    try:
        for stage in stages:
            print(f"== {stage}", file=sys.stderr, flush=True)
            report = pipeline.run_stage(stage, run_dir, config)
    except ImitateError as err:
        print(f"imitate {args.command}: error: {err}", file=sys.stderr)
        return 1
    print(summary(report, stages, run_dir))
    return 0


def summary(report: dict, stages: tuple[str, ...], run_dir: Path) -> str:
    """The stage-timing table and the headline numbers of ``report``."""
    lines = ["", f"{'stage':<10} {'seconds':>8}"]
    timings = report.get("timings", {})
    lines += [f"{stage:<10} {timings[stage]:8.1f}" for stage in stages]
    lines.append(f"{'total':<10} {sum(timings[s] for s in stages):8.1f}")
    headline = {
        "demos": ("detected", "expected"),
        "perception": ("pos_err_mm_median", "pos_err_mm_p95", "angle_err_deg_median"),
        "learning": ("bic", "n_components", "n_components_fast_bic", "n_components_full_bic"),
        "optimization": ("min_distance_m", "pour_phase_err_m", "pour_phase_err_deg"),
        "replay": ("pour_fraction", "spilled", "min_distance_m", "success"),
    }
    lines.append("")
    for section, keys in headline.items():
        if section in report:
            values = ", ".join(f"{k} {_fmt(report[section][k])}" for k in keys)
            lines.append(f"{section}: {values}")
    lines.append("")
    for name in ("video", "report"):
        if name in report.get("artifacts", {}):
            lines.append(f"{name}: {run_dir / report['artifacts'][name]}")
    return "\n".join(lines)


def _fmt(value) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)


if __name__ == "__main__":
    sys.exit(main())
