"""The ``imitate`` command line: the sub-commands' arguments, the settings' flags, and the run's
settings from the flags given.

The command line is built for the sub-command given only, from plain constants
(:mod:`imitate.defaults`) and the settings' declarations (:mod:`imitate.stages.config`): no
``--help`` loads MuJoCo, numba, SciPy or matplotlib.
"""

from __future__ import annotations

import argparse
import dataclasses
import difflib
import logging
import re
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

from imitate import __version__
from imitate.errors import ImitateError, shortened
from imitate.stages.table import NAMES, RUN_HELP, STAGES

if TYPE_CHECKING:
    from imitate.stages.config import RunConfig, Setting

__all__ = ["COMMANDS", "DEFAULT_RUN", "build_parser", "config_for", "stages_of", "starts_run",
           "unrecognized"]

DEFAULT_RUN = Path("runs/latest")
EXPORT_HELP = (
    "the robot's replay and the teacher's demonstrations as datasets (pip install "
    "'imitate-humanoid[export]')"
)
EVAL_HELP = "reproduce a run's learned model in seeded variations (obstacles, grasps, physics)"
COMPARE_HELP = (
    "similarity weightings on the same variations, paired over teachers: a primary endpoint in "
    "development and confirmation teachers with intervals, power and a clustered model"
)
SENSITIVITY_HELP = (
    "the task's measured tolerance per teacher: its reproduction moved in the critical phase "
    "along each task dimension and eigen-direction (14 for eq. 1) and replayed, kept for the "
    "importance weighting"
)
COMMANDS = {
    **{s.name: s.help for s in STAGES}, "run": RUN_HELP, "export": EXPORT_HELP,
    "eval": EVAL_HELP, "compare": COMPARE_HELP, "sensitivity": SENSITIVITY_HELP,
}


OPTION = "option_"  # prefix of the attributes of the task settings' flags


class Parser(argparse.ArgumentParser):
    """argparse's parser whose errors are their one line, without the usage of every flag
    above it (a dozen lines for ``imitate run``; ``--help`` shows them)."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {shortened(message)}\n")


def build_parser(full: Iterable[str] | None = None) -> argparse.ArgumentParser:
    """The command line: every sub-command, with its arguments for those in ``full`` (default:
    all). The parsed namespace holds the sub-command's name as ``command`` and its parser as
    ``parser`` (its errors: one line)."""
    full = COMMANDS if full is None else tuple(full)
    parser = Parser(
        prog="imitate",
        description="Task-level imitation learning of bimanual tasks (Muehlig et al., ICRA "
        "2009), end to end in MuJoCo: pouring, inserting (--task).",
    )
    parser.add_argument("--version", action="version", version=f"imitate {__version__}")
    _add_verbosity(parser, logging.INFO)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command, text in COMMANDS.items():
        sub = commands.add_parser(command, help=text, description=text)
        sub.set_defaults(parser=sub)
        _add_verbosity(sub, argparse.SUPPRESS)
        if command not in full:
            continue
        if command == "export":
            _add_export(sub)
        elif command == "eval":
            _add_eval(sub)
        elif command == "compare":
            _add_compare(sub)
        elif command == "sensitivity":
            _add_sensitivity(sub)
        else:
            _add_run(sub, command)
    return parser


def stages_of(command: str) -> tuple[str, ...]:
    """The stages ``command`` runs: all for ``run``, else its own."""
    return NAMES if command == "run" else (command,)


def starts_run(command: str) -> bool:
    """Whether ``command`` starts a run (from the defaults, making the directory)."""
    return command in ("run", "observe")


def config_for(args: argparse.Namespace, base: RunConfig) -> RunConfig:
    """The run's configuration: ``base`` (the run directory's ``config.json`` for a later
    stage, the defaults for ``run`` and ``observe``) with ``--quick`` and the given settings
    applied."""
    from imitate.envs import tasks
    from imitate.stages.config import RunConfig, settings

    stages = stages_of(args.command)
    owned = {name for name, s, _ in settings(stages) if s.flag}
    given = {k: v for k, v in vars(args).items() if k in owned or k == "seed"}
    options = {k.removeprefix(OPTION): v for k, v in vars(args).items() if k.startswith(OPTION)}
    task = given.get("task", base.task)
    values = base.to_json()
    if task != base.task:  # another task: its own settings from their defaults
        values.update(task=task, options=None)
    values["options"] = dict(values["options"] or {})
    if args.quick:
        quick = RunConfig.quick(task=task).to_json()
        fresh = starts_run(args.command)
        values.update({k: v for k, v in quick.items() if k != "options" and (fresh or k in owned)})
        declared = tasks.options(task)
        values["options"].update({n: v for n, v in quick["options"].items()
                                  if fresh or declared[n].stage in stages})
    values["options"].update(options)
    return RunConfig.from_json({**values, **given})


def unrecognized(unknown: list[str], sub: argparse.ArgumentParser) -> str:
    """Argparse's message for ``unknown`` arguments, with the closest flag of ``sub`` for each
    unknown flag (``--colision-weight``: did you mean ``--collision-weight``?)."""
    listed = re.findall(r"^  (-\S.*?)(?:  |$)", sub.format_help(), re.MULTILINE)  # the options
    flags = [flag for line in listed for flag in re.findall(r"--[\w-]+", line)]
    guesses = [
        f"{arg} (did you mean {close[0]}?)" if close else arg
        for arg in unknown
        for close in [difflib.get_close_matches(arg.split("=")[0], flags, n=1)
                      if arg.startswith("--") else []]
    ]
    return f"unrecognized arguments: {' '.join(guesses)}"


def _add_verbosity(parser: argparse.ArgumentParser, default) -> None:
    """``-v`` and ``-q``, before or after the sub-command (there the default is ``SUPPRESS``,
    so as not to undo one given before it)."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-v", "--verbose", dest="log_level", action="store_const",
                       const=logging.DEBUG, default=default, help="also print debug lines")
    group.add_argument("-q", "--quiet", dest="log_level", action="store_const",
                       const=logging.WARNING, default=default,
                       help="print only warnings and errors (and the summary on stdout)")


def _add_run(sub: argparse.ArgumentParser, command: str) -> None:
    """The arguments of ``run`` and of a stage's sub-command: the run directory and the
    settings the command's stages read."""
    from imitate.stages.config import settings

    sub.add_argument("run_dir", nargs="?", type=Path, metavar="RUN_DIR",
                     help=f"run directory (default {DEFAULT_RUN}); same as --out")
    sub.add_argument("--out", type=Path, metavar="DIR", help="run directory")
    _add_settings(sub, settings([None]))
    sub.add_argument("--quick", action="store_true",
                     help="small images, 3 demonstrations, short optimization (tests)")
    sub.add_argument("--force", action="store_true",
                     help="use input artifacts that are stale or from another run (see "
                     "manifest.json) instead of refusing them")
    if starts_run(command):
        sub.add_argument("--into-existing", action="store_true",
                         help="start the run in a non-empty folder that is not a run directory "
                         "(no manifest.json) instead of refusing it; files of the names a run "
                         "writes are replaced")
    for stage in stages_of(command):
        group = sub.add_argument_group(f"{stage} settings")
        _add_settings(group, settings([stage]))
        _add_task_options(group, stage)


def _add_task_options(group, stage: str) -> None:
    """One flag per task setting first used by ``stage`` (``--particles``), for every task
    that has it, its help with each task's range and default; a flag not given leaves no
    attribute. The flag takes what any of its tasks accepts; the run's task checks it."""
    from imitate.envs import tasks

    declared: dict[str, dict[str, tasks.Option]] = {}
    for task in tasks.NAMES:
        for name, option in tasks.options(task).items():
            if option.stage == stage:
                declared.setdefault(name, {})[task] = option
    for name, by_task in declared.items():
        first = next(iter(by_task.values()))
        option = dataclasses.replace(first, low=min(o.low for o in by_task.values()),
                                     high=max(o.high for o in by_task.values()))
        kind = int if option.integer else float

        def read(text: str, name: str = name, option: tasks.Option = option) -> float:
            return option.value(name, (int if option.integer else float)(text))

        read.__name__ = kind.__name__  # argparse names it in "invalid float value"
        each = "; ".join(f"{task} {o.low:g}..{o.high:g}, default {o.default:g}"
                         for task, o in by_task.items())
        group.add_argument(
            f"--{name.replace('_', '-')}", dest=OPTION + name, type=_argument_type(read),
            default=argparse.SUPPRESS, metavar=kind.__name__.upper(),
            help=f"{first.help} ({each})",
        )


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


def _add_export(sub: argparse.ArgumentParser) -> None:
    """The ``export`` sub-command's arguments (see :mod:`imitate.export`)."""
    from imitate.defaults import EXPORT_FORMATS as FORMATS

    sub.add_argument("run_dir", nargs="?", type=Path, default=DEFAULT_RUN, metavar="RUN_DIR",
                     help=f"run directory (default {DEFAULT_RUN})")
    sub.add_argument("--format", required=True, choices=FORMATS,
                     help="minari: a Minari datasets root; hdf5: robomimic-style files; "
                     "lerobot: LeRobot v3.0 datasets")
    sub.add_argument("--out", type=Path, metavar="PATH",
                     help="output directory, must not exist (default RUN_DIR/export/FORMAT; "
                     "minari: Minari's datasets root, MINARI_DATASETS_PATH or ~/.minari/datasets)")
    sub.add_argument("--images", action="store_true",
                     help="also store camera images at every step: the robot's workspace camera, "
                     "the teacher as the stereo eyes saw it")
    sub.add_argument("--from-eval", type=Path, metavar="EVAL_DIR",
                     help="the robot's episodes: one per variation of the evaluation in EVAL_DIR "
                     "(the folder imitate eval printed), its settings and outcome in each "
                     "episode's metadata, instead of the run's plan (hdf5, lerobot)")


def _add_eval(sub: argparse.ArgumentParser) -> None:
    """The ``eval`` sub-command's arguments (see :mod:`imitate.evaluation`); the suite's keys
    in its help."""
    from imitate.defaults import SIMILARITIES

    _add_variations(sub, teachers=1)
    sub.add_argument("--out", type=Path, metavar="DIR",
                     help="folder of the results, summary and page (default "
                     "RUN_DIR/eval/SUITE-wWEIGHT-SIMILARITY, e.g. eval/default-w10000-variance: "
                     "one per suite, weight and weighting)")
    sub.add_argument("--similarity", choices=SIMILARITIES, metavar="NAME", dest="weighting",
                     help=f"replaces the suite's similarity weighting: one of {SIMILARITIES}")
    sub.add_argument("--videos", type=_count, default=3, metavar="K",
                     help="videos of the first K failures (default 3)")
    sub.formatter_class = argparse.RawDescriptionHelpFormatter
    sub.epilog = "suite keys (a .toml or .json file of them; the default of each):\n" + "\n".join(
        f"  {name} ({_fmt_default(key.default)}): {key.help}{owners}"
        for name, (key, owners) in _suite_keys().items()
    )


def _suite_keys() -> dict[str, tuple[Any, str]]:
    """Every task's suite keys, each once, with the tasks that have it (``" (task ...)"``; ``""``
    for the keys of every task); a key's default is the first task's."""
    from imitate.envs import tasks
    from imitate.evaluation.suite import KEYS, keys

    found: dict[str, tuple[Any, list[str]]] = {}
    for task in tasks.NAMES:
        for name, key in keys(task).items():
            found.setdefault(name, (key, []))[1].append(task)
    return {
        name: (key, "" if name in KEYS else f" (task {', '.join(owners)})")
        for name, (key, owners) in found.items()
    }


def _count(text: str) -> int:
    """A whole number >= 0, for argparse."""
    value = int(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"{value} not accepted: a whole number >= 0")
    return value


def _fmt_default(value: Any) -> str:
    """A suite key's default as a suite file writes it: ``[low, high]`` for a range."""
    if isinstance(value, tuple):
        return "[" + ", ".join(map(str, value)) + "]"
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def _add_compare(sub: argparse.ArgumentParser) -> None:
    """The ``compare`` sub-command's arguments (see :mod:`imitate.evaluation.compare`)."""
    from imitate.defaults import SIMILARITIES

    # the weightings compared unless told: eq. 21, the even spread of its weight, its inverse
    # (a negative control) and minimal intervention
    compared = ("variance", "uniform", "inverted", "precision")
    _add_variations(sub, teachers=10)
    sub.add_argument("--similarity", default=",".join(compared), metavar="A,B,...",
                     dest="weightings",
                     help=f"weightings to compare, comma-separated, of {', '.join(SIMILARITIES)} "
                     f"(default {','.join(compared)})")
    sub.add_argument("--confirm", type=_count, default=0, metavar="N",
                     help="confirmation teachers beside --teachers: seeds 1000 and up, which "
                     "nothing was tuned on; the primary endpoint is reported in each block and "
                     "whether the development verdict replicated (default 0: none)")
    sub.add_argument("--primary", metavar="A-B",
                     help="the primary endpoint, declared before the runs: the success rate of "
                     "weighting A minus B per teacher (default: the first two of --similarity)")
    sub.add_argument("--sweep", metavar="KEY=V1,V2,...", dest="levels",
                     help="compare at every value of a numeric suite key (a dose-response "
                     "curve per weighting and its ED50), e.g. path_length_weight=10,20,40,70 "
                     "or collision_weight=100,300,1000,3000,10000")


def _add_sensitivity(sub: argparse.ArgumentParser) -> None:
    """The ``sensitivity`` sub-command's arguments (see
    :mod:`imitate.evaluation.sensitivity_run`)."""
    sub.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="run directory with model.npz")
    sub.add_argument("--teachers", type=int, default=1, metavar="N",
                     help="teachers: the run's and the next seeds' (default 1)")
    sub.add_argument("--confirm", type=_count, default=0, metavar="N",
                     help="confirmation teachers beside --teachers: seeds 1000 and up (default 0)")
    sub.add_argument("--magnitudes", default="1,2,4", metavar="K1,K2,...",
                     help="moves either way [tolerances: 1 cm, 2 deg, 0.05], increasing "
                     "(default 1,2,4)")
    sub.add_argument("--seeds", type=int, default=3, metavar="S",
                     help="replays of each moved plan (default 3)")
    sub.add_argument("--workers", type=int, metavar="W",
                     help="local worker processes (default: one per core)")
    sub.add_argument("--against", type=Path, metavar="COMPARE_JSON",
                     help="a compare.json of variance and uniform: each alignment set beside "
                     "their per-teacher success difference")


def _add_variations(sub, teachers: int) -> None:
    """The arguments ``eval`` and ``compare`` share: the run and its task, the suite and its
    draw, the teachers, where the variations run."""
    from imitate.envs import tasks

    sub.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="run directory with model.npz")
    sub.add_argument("--task", choices=tasks.NAMES, metavar="NAME",
                     help=f"the run's task, checked (default: the run's config.json's, else "
                     f"{tasks.DEFAULT}); one of {', '.join(tasks.NAMES)}")
    sub.add_argument("--suite", metavar="NAME|FILE",
                     help="suite of variations of the run's task: default (the built-in one), "
                     "one the task ships (the stems of its suites/*.toml) or a .toml or .json "
                     "file (default: the built-in one)")
    sub.add_argument("--n", type=int, metavar="N",
                     help="variations to run (default: the suite's 'variations', 100 built in)")
    sub.add_argument("--seed", type=_count, default=0, metavar="S",
                     help="seed the variations are drawn with, >= 0 (default 0)")
    sub.add_argument("--teachers", type=int, default=teachers, metavar="N",
                     help=f"teachers whose learned models reproduce every variation: the run's "
                     f"and the next seeds', each observed and learned once (default {teachers})")
    sub.add_argument("--workers", type=int, metavar="W",
                     help="local worker processes (default: one per core)")
    sub.add_argument("--ray", metavar="ADDRESS",
                     help="run the variations as Ray tasks on the cluster at ADDRESS ('auto': "
                     "the one Ray finds); needs imitate-humanoid[ray]")
    sub.add_argument("--collision-weight", type=float, metavar="W", dest="weight",
                     help="replaces the suite's collision_weight, 0..1e6")
