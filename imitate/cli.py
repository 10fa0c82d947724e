"""The ``imitate`` command: one sub-command per stage of a run, and ``run`` for all of them.

    imitate run --out runs/latest             # watch, learn, optimise, pour, plot
    imitate run --quick --out runs/quick      # small images, 3 demonstrations: under a minute
    imitate optimize runs/latest --collision-weight 30   # re-plan with the learned model
    imitate replay runs/latest && imitate figures runs/latest

Each stage reads the previous stage's artifacts in the run directory (see
:mod:`imitate.stages`); settings given on the command line replace those in its
``config.json``, the rest are kept.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from imitate.config import RunConfig, Setting, load_config, settings
from imitate.errors import ImitateError
from imitate.stages import NAMES, RUN_HELP, STAGES

__all__ = ["main"]

DEFAULT_RUN = Path("runs/latest")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="imitate",
        description="Task-level imitation learning of pouring (Muehlig et al., ICRA 2009), "
        "end to end in MuJoCo.",
    )
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    helps = {**{s.name: s.help for s in STAGES}, "run": RUN_HELP}
    for command, text in helps.items():
        sub = commands.add_parser(command, help=text, description=text)
        sub.add_argument("run_dir", nargs="?", type=Path, metavar="RUN_DIR",
                         help=f"run directory (default {DEFAULT_RUN}); same as --out")
        sub.add_argument("--out", type=Path, metavar="DIR", help="run directory")
        _add_settings(sub, settings([None]))
        sub.add_argument("--quick", action="store_true",
                         help="small images, 3 demonstrations, short optimisation (tests)")
        for stage in _stages(command):
            _add_settings(sub.add_argument_group(f"{stage} settings"), settings([stage]))
    _add_eval(commands)
    return parser


def _add_eval(commands) -> None:
    """The ``eval`` sub-command's arguments (see :mod:`imitate.evaluation`)."""
    text = "reproduce a run's learned model in seeded variations (obstacles, grasps, physics)"
    sub = commands.add_parser("eval", help=text, description=text)
    sub.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="run directory with model.npz")
    sub.add_argument("--suite", type=Path, metavar="FILE",
                     help="suite of variations, .toml or .json (default: the built-in one)")
    sub.add_argument("--n", type=int, metavar="N",
                     help="variations to run (default: the suite's 'variations', 100 built in)")
    sub.add_argument("--seed", type=int, default=0, metavar="S",
                     help="seed the variations are drawn with (default 0)")
    sub.add_argument("--workers", type=int, metavar="W",
                     help="local worker processes (default: one per core)")
    sub.add_argument("--ray", metavar="ADDRESS",
                     help="run the variations as Ray tasks on the cluster at ADDRESS ('auto': "
                     "the one Ray finds); needs imitate[ray]")
    sub.add_argument("--collision-weight", type=float, metavar="W", dest="weight",
                     help="replaces the suite's collision_weight")
    sub.add_argument("--videos", type=int, default=3, metavar="K",
                     help="videos of the first K failures (default 3)")


def _add_settings(group, declared: list[tuple[str, Setting, Any]]) -> None:
    """One flag per declared setting that has one; a flag not given leaves no attribute."""
    for name, s, default in declared:
        if s.flag is None:
            continue
        if isinstance(default, bool):
            group.add_argument(s.flag, dest=name, action=argparse.BooleanOptionalAction,
                               default=argparse.SUPPRESS, help=s.describe(default))
            continue
        kind = s.parse or type(default)
        group.add_argument(
            s.flag, dest=name, type=_argument_type(kind), choices=s.choices,
            default=argparse.SUPPRESS, help=s.describe(default),
            metavar=None if s.choices else s.metavar or kind.__name__.upper(),
        )


def _argument_type(parse: Callable[[str], Any]) -> Callable[[str], Any]:
    """``parse`` with its ``ImitateError`` shown by argparse as the flag's error."""

    def read(text: str) -> Any:
        try:
            return parse(text)
        except ImitateError as err:
            raise argparse.ArgumentTypeError(str(err)) from None

    read.__name__ = parse.__name__  # argparse names it in "invalid int value"
    return read


def _stages(command: str) -> tuple[str, ...]:
    return NAMES if command == "run" else (command,)


def config_for(args: argparse.Namespace, run_dir: Path) -> RunConfig:
    """The run's configuration: ``config.json`` of ``run_dir`` for a later stage (a new one
    for ``run`` and ``observe``), with ``--quick`` and the given settings applied."""
    owned = {name for name, s, _ in settings(_stages(args.command)) if s.flag}
    given = {k: v for k, v in vars(args).items() if k in owned or k == "seed"}
    fresh = args.command in ("run", "observe")
    base = RunConfig() if fresh else load_config(run_dir)
    if args.quick:
        quick = RunConfig.quick().to_json()
        base = RunConfig.from_json(
            {**base.to_json(), **{k: v for k, v in quick.items() if fresh or k in owned}}
        )
    return RunConfig.from_json({**base.to_json(), **given})


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command == "eval":
        return _eval(args)
    if args.run_dir and args.out and args.run_dir != args.out:
        parser.error(f"two run directories given: {args.run_dir} and --out {args.out}; give one")
    run_dir = args.out or args.run_dir or DEFAULT_RUN
    from imitate import pipeline  # the stages (matplotlib, rendering): once the arguments are fine

    try:
        config = config_for(args, run_dir)
    except ImitateError as err:
        parser.error(str(err))
    stages = _stages(args.command)
    try:
        for stage in stages:
            print(f"== {stage}", file=sys.stderr, flush=True)
            report = pipeline.run_stage(stage, run_dir, config)
    except ImitateError as err:
        print(f"imitate {args.command}: error: {err}", file=sys.stderr)
        return 1
    print(summary(report, stages, run_dir))
    return 0


def _eval(args: argparse.Namespace) -> int:
    """``imitate eval``: the evaluation of ``args.run_dir``; prints its summary."""
    from imitate import evaluation  # MuJoCo and the planner: once the arguments are fine

    try:
        suite = evaluation.load_suite(args.suite) if args.suite else evaluation.Suite.default()
        if args.weight is not None:
            suite = suite.replace(collision_weight=args.weight)
        summary = evaluation.evaluate(
            args.run_dir, suite, n=args.n, seed=args.seed, workers=args.workers,
            ray=args.ray, videos=args.videos,
        )
    except ImitateError as err:
        print(f"imitate eval: error: {err}", file=sys.stderr)
        return 1
    print(evaluation.text(summary, args.run_dir / "eval"))
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
