"""The ``imitate`` command: one sub-command per stage of a run, and ``run`` for all of them.

    imitate run --out runs/latest             # watch, learn, optimize, pour, plot
    imitate run --quick --out runs/quick      # small images, 3 demonstrations: under a minute
    imitate optimize runs/latest --collision-weight 30   # re-plan with the learned model
    imitate replay runs/latest && imitate figures runs/latest

Each stage reads the previous stage's artifacts in the run directory (see
:mod:`imitate.rundir.table`); settings given on the command line replace those in its
``config.json``, the rest are kept. One command at a time holds a run directory (see
:mod:`imitate.rundir`); a stage refuses inputs that are stale or from another run unless
``--force`` (see :mod:`imitate.stages.provenance`); ``run`` and ``observe`` start a run only in a
new or empty folder or a run directory (``--into-existing``: in another folder). Errors are one
line on stderr: exit status 1, 2 for a bad flag, 130 for Ctrl-C and 143 for SIGTERM; a stage that
does not finish changes nothing.

Progress goes to stderr (``-q`` leaves warnings and errors, ``-v`` adds debug lines; see
:mod:`imitate.cli.console`). The command line is built for the sub-command given only, from
plain constants (:mod:`imitate.defaults`): no ``--help`` loads MuJoCo, numba, SciPy or matplotlib.
"""

from __future__ import annotations

import argparse
import difflib
import logging
import os
import sys
from collections.abc import Callable, Iterable
from contextlib import ExitStack
from pathlib import Path
from typing import TYPE_CHECKING, Any

from imitate import __version__
from imitate.cli import console
from imitate.errors import ImitateError
from imitate.rundir.table import NAMES, RUN_HELP, STAGES

if TYPE_CHECKING:
    from imitate.stages.config import RunConfig, Setting

__all__ = ["main"]

log = logging.getLogger(__name__)

DEFAULT_RUN = Path("runs/latest")
EXPORT_HELP = (
    "the robot's replay and the teacher's demonstrations as datasets (pip install "
    "'imitate-humanoid[export]')"
)
EVAL_HELP = "reproduce a run's learned model in seeded variations (obstacles, grasps, physics)"
COMPARE_HELP = (
    "similarity weightings on the same variations, paired: success (McNemar) and how far the "
    "pour moved (Wilcoxon)"
)
COMMANDS = {
    **{s.name: s.help for s in STAGES}, "run": RUN_HELP, "export": EXPORT_HELP,
    "eval": EVAL_HELP, "compare": COMPARE_HELP,
}


def build_parser(full: Iterable[str] | None = None) -> argparse.ArgumentParser:
    """The command line: every sub-command, with its arguments for those in ``full`` (default:
    all). Building it loads no MuJoCo, numba, SciPy or matplotlib (see :mod:`imitate.defaults`):
    ``--help`` is quick."""
    full = COMMANDS if full is None else tuple(full)
    parser = argparse.ArgumentParser(
        prog="imitate",
        description="Task-level imitation learning of pouring (Muehlig et al., ICRA 2009), "
        "end to end in MuJoCo.",
    )
    parser.add_argument("--version", action="version", version=f"imitate {__version__}")
    _add_verbosity(parser, logging.INFO)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for command, text in COMMANDS.items():
        sub = commands.add_parser(command, help=text, description=text)
        _add_verbosity(sub, argparse.SUPPRESS)
        if command not in full:
            continue
        if command == "export":
            _add_export(sub)
        elif command == "eval":
            _add_eval(sub)
        elif command == "compare":
            _add_compare(sub)
        else:
            _add_run(sub, command)
    return parser


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
    if _starts_run(command):
        sub.add_argument("--into-existing", action="store_true",
                         help="start the run in a non-empty folder that is not a run directory "
                         "(no manifest.json) instead of refusing it; files of the names a run "
                         "writes are replaced")
    for stage in _stages(command):
        _add_settings(sub.add_argument_group(f"{stage} settings"), settings([stage]))


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


def export_command(args: argparse.Namespace) -> int:
    """``imitate export``: writes the datasets, prints where."""
    from imitate.export import export

    try:
        with console.terminated_as_exception():
            out = export(
                args.run_dir, args.format, args.out, images=args.images, from_eval=args.from_eval
            )
    except (ImitateError, OSError) as err:  # OSError: disk full, no permission
        return console.fail("export", str(err), 1)
    except KeyboardInterrupt:
        return console.fail("export", "interrupted (Ctrl-C); nothing was written", 130)
    except console.Terminated:
        return console.fail("export", "terminated (SIGTERM); nothing was written", 143)
    print(out)
    return 0


def _add_verbosity(parser: argparse.ArgumentParser, default) -> None:
    """``-v`` and ``-q``, before or after the sub-command (there the default is ``SUPPRESS``,
    so as not to undo one given before it)."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("-v", "--verbose", dest="log_level", action="store_const",
                       const=logging.DEBUG, default=default, help="also print debug lines")
    group.add_argument("-q", "--quiet", dest="log_level", action="store_const",
                       const=logging.WARNING, default=default,
                       help="print only warnings and errors (and the summary on stdout)")


def _add_eval(sub: argparse.ArgumentParser) -> None:
    """The ``eval`` sub-command's arguments (see :mod:`imitate.evaluation`); the suite's keys
    in its help."""
    from imitate.defaults import SIMILARITIES
    from imitate.evaluation.suite import KEYS

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
        f"  {name} ({_fmt_default(key.default)}): {key.help}" for name, key in KEYS.items()
    )


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
    sub.add_argument("--sweep", metavar="KEY=V1,V2,...", dest="levels",
                     help="compare at every value of a numeric suite key (a dose-response "
                     "curve per weighting and its ED50), e.g. path_length_weight=10,20,40,70 "
                     "or collision_weight=100,300,1000,3000,10000")


def _add_variations(sub, teachers: int) -> None:
    """The arguments ``eval`` and ``compare`` share: the run, the suite and its draw, the
    teachers, where the variations run."""
    from imitate.evaluation.suite import SUITE_NAMES

    sub.add_argument("run_dir", type=Path, metavar="RUN_DIR", help="run directory with model.npz")
    sub.add_argument("--suite", metavar="NAME|FILE",
                     help=f"suite of variations: a shipped one ({', '.join(SUITE_NAMES)}) or "
                     "a .toml or .json file (default: the built-in one)")
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


def config_for(args: argparse.Namespace, base: RunConfig) -> RunConfig:
    """The run's configuration: ``base`` (the run directory's ``config.json`` for a later
    stage, the defaults for ``run`` and ``observe``) with ``--quick`` and the given settings
    applied."""
    from imitate.stages.config import RunConfig, settings

    owned = {name for name, s, _ in settings(_stages(args.command)) if s.flag}
    given = {k: v for k, v in vars(args).items() if k in owned or k == "seed"}
    if args.quick:
        quick = RunConfig.quick().to_json()
        fresh = _starts_run(args.command)
        base = RunConfig.from_json(
            {**base.to_json(), **{k: v for k, v in quick.items() if fresh or k in owned}}
        )
    return RunConfig.from_json({**base.to_json(), **given})


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = build_parser(full=[a for a in argv if a in COMMANDS][:1])
    args, unknown = parser.parse_known_args(argv)
    sub = _command_parser(parser, args.command)
    if unknown:
        sub.error(_unrecognized(unknown, sub))
    console.prepare()
    console.log_to_stderr(args.log_level)
    if args.command == "export":
        return export_command(args)
    if args.command in ("eval", "compare"):
        return _eval(args)
    if args.run_dir and args.out and args.run_dir != args.out:
        sub.error(f"two run directories given: {args.run_dir} and --out {args.out}; give one")
    run_dir = args.out or args.run_dir or DEFAULT_RUN
    command = " ".join(["imitate", *argv])
    stages, stage = _stages(args.command), None
    fresh = _starts_run(args.command)
    from imitate import numba_cache
    from imitate.rundir.lock import locked
    from imitate.stages.config import RunConfig, load_config

    manifest = _manifest_id(run_dir)  # as the last stage that finished left it
    try:
        if fresh and not args.into_existing:
            _refuse_foreign(run_dir)
        with console.terminated_as_exception(), locked(run_dir, command, create=fresh):
            from imitate.figures import drawing  # the stages: once the directory is ours
            from imitate.stages import runner

            base = RunConfig() if fresh else load_config(run_dir)
            try:
                config = config_for(args, base)
            except ImitateError as err:
                sub.error(str(err))
            if fresh:
                _warn_if_replaced(run_dir, config)
            log.debug("run directory %s, settings %s", run_dir, config.to_json())
            with ExitStack() as ahead:
                for stage in stages:
                    if stage == "learn" and stages[-1] == "figures":
                        # the figures' worker process loads beside learn, optimize and replay
                        # (observe keeps every core busy)
                        ahead.enter_context(drawing.ahead())
                    log.info("== %s", stage)
                    notice = numba_cache.compile_notice(stage)
                    if notice:
                        log.info(notice)
                    report = runner.run_stage(stage, run_dir, config, force=args.force)
                    manifest = _manifest_id(run_dir)
    except ImitateError as err:
        return console.fail(args.command, str(err), 1)
    except OSError as err:
        return console.fail(args.command, str(err), 1)
    except (KeyboardInterrupt, console.Terminated) as err:
        how, status = ("interrupted (Ctrl-C)", 130) if isinstance(err, KeyboardInterrupt) else (
            "terminated (SIGTERM)", 143
        )
        stopped = console.stopped(how, stage, run_dir, _manifest_id(run_dir) != manifest)
        if isinstance(err.__context__, ImitateError):  # the signal came as the stage failed
            stopped = f"{how} as stage {stage} failed: {err.__context__}"
        return console.fail(args.command, stopped, status)
    print(console.summary(report, stages, run_dir))
    return 0


def _command_parser(parser: argparse.ArgumentParser, command: str) -> argparse.ArgumentParser:
    """The sub-command's parser (its errors show its usage)."""
    action = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return action.choices[command]


def _unrecognized(unknown: list[str], sub: argparse.ArgumentParser) -> str:
    """Argparse's message for ``unknown`` arguments, with the closest flag of ``sub`` for each
    unknown flag (``--colision-weight``: did you mean ``--collision-weight``?)."""
    flags = [s for a in sub._actions for s in a.option_strings]
    guesses = [
        f"{arg} (did you mean {close[0]}?)" if close else arg
        for arg in unknown
        for close in [difflib.get_close_matches(arg.split("=")[0], flags, n=1)
                      if arg.startswith("--") else []]
    ]
    return f"unrecognized arguments: {' '.join(guesses)}"


def _warn_if_replaced(run_dir: Path, config: RunConfig) -> None:
    """A warning naming the settings that differ when a run starts anew in ``run_dir`` over one
    made with other settings (``imitate run runs/quick`` without ``--quick``)."""
    from imitate.stages.config import load_config

    try:
        before = load_config(run_dir).to_json()
    except ImitateError:  # no run there yet, or one this imitate cannot read: nothing to name
        return
    now = config.to_json()
    changed = [
        f"{name} {before.get(name)} -> {value}" for name, value in now.items()
        if value != before.get(name)
    ]
    if changed:
        log.warning(
            "%s holds a run made with other settings; this run replaces it with: %s",
            run_dir, ", ".join(changed),
        )


def _refuse_foreign(run_dir: Path) -> None:
    """Raise ``ImitateError`` if ``run_dir`` is a folder holding files but no run: neither
    ``manifest.json`` nor the lock of an ``imitate`` command killed before its first stage
    finished."""
    from imitate.rundir.lock import left_by_imitate
    from imitate.stages.provenance import MANIFEST

    if not run_dir.is_dir() or (run_dir / MANIFEST).exists() or left_by_imitate(run_dir):
        return
    names = sorted(entry.name for entry in run_dir.iterdir())
    if not names:
        return
    more = f" and {len(names) - 3} more" if len(names) > 3 else ""
    raise ImitateError(
        f"{run_dir} holds {', '.join(names[:3])}{more} and is not a run directory (no "
        f"{MANIFEST}); give another folder, or add --into-existing to start a run in it anyway "
        f"(its files of the names a run writes, such as config.json, are replaced)"
    )


def _manifest_id(run_dir: Path) -> tuple[int, int] | None:
    """Device and inode of ``run_dir``'s ``manifest.json`` (a stage's commit renames a new one
    into place, last), or None if there is none."""
    from imitate.stages.provenance import MANIFEST

    try:
        found = os.stat(run_dir / MANIFEST)
    except OSError:
        return None
    return found.st_dev, found.st_ino


def _starts_run(command: str) -> bool:
    """Whether ``command`` starts a run (from the defaults, making the directory)."""
    return command in ("run", "observe")


def _eval(args: argparse.Namespace) -> int:
    """``imitate eval`` or ``imitate compare`` of ``args.run_dir``; prints its summary."""
    from imitate import evaluation  # MuJoCo and the planner: once the arguments are fine
    from imitate.evaluation import compare

    kept = "the finished variations are kept; run it again to go on"
    try:
        name, suite = evaluation.named_suite(args.suite)
        if args.weight is not None:
            suite = suite.replace(collision_weight=args.weight)
        if args.command == "eval" and args.weighting is not None:
            suite = suite.replace(similarity=args.weighting)
        if args.command == "eval":
            folder = args.out or evaluation.default_out(args.run_dir, name, suite)
        else:
            folder = compare.out_folder(args.run_dir, name, args.levels)
        kept = f"the finished variations are kept in {folder}; run it again to go on"
        with console.terminated_as_exception():
            if args.command == "compare":
                sweep = compare.parse_sweep(args.levels) if args.levels else None
                result = compare.compare(
                    args.run_dir, suite, args.weightings.split(","), name=name, n=args.n,
                    seed=args.seed, n_teachers=args.teachers, sweep=sweep, workers=args.workers,
                    ray=args.ray,
                )
                ran = result["run"]
                text = (f"{compare.markdown(result)}\n\nran {ran['ran']} variations in "
                        f"{ran['wall_seconds']:.0f} s ({ran['backend']}, workers "
                        f"{ran['workers']}); results: {folder}")
            else:
                summary = evaluation.evaluate(
                    args.run_dir, suite, n=args.n, seed=args.seed, n_teachers=args.teachers,
                    workers=args.workers, ray=args.ray, videos=args.videos, out=folder,
                )
                text = evaluation.text(summary, folder)
    except ImitateError as err:
        return console.fail(args.command, str(err), 1)
    except OSError as err:  # disk full, no permission: the finished variations are kept
        return console.fail(args.command, f"{err}; {kept}", 1)
    except KeyboardInterrupt:
        return console.fail(args.command, f"interrupted (Ctrl-C); {kept}", 130)
    except console.Terminated:
        return console.fail(args.command, f"terminated (SIGTERM); {kept}", 143)
    print(text)
    return 0

