"""The ``imitate`` sub-commands' work: the stages (``run`` and one per stage), ``eval`` and
``compare``, ``export``; each with one exit-status mapping, :func:`exits`.

A command's errors are one line on stderr: exit status 1 for an ``ImitateError`` or an
``OSError`` (disk full, no permission), 130 for Ctrl-C and 143 for SIGTERM. The library names its
parameters in its errors (``similarities='variance,flat' not accepted``); the line names the
command-line flags instead (:data:`FLAGS`).
"""

from __future__ import annotations

import argparse
import logging
import os
import re
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from imitate.cli import console
from imitate.cli.parser import DEFAULT_RUN, config_for, stages_of, starts_run
from imitate.errors import ImitateError
from imitate.rundir.layout import MANIFEST

if TYPE_CHECKING:
    from imitate.stages.config import RunConfig

__all__ = ["FLAGS", "Exit", "eval_command", "exits", "export_command", "stages_command"]

log = logging.getLogger(__name__)

# The library's parameters and the flags that set them, for its errors (``name='value'``).
FLAGS = {
    "similarities": "--similarity", "sweep": "--sweep", "from_eval": "--from-eval",
    "format": "--format",
}


@dataclass
class Exit:
    """How an :func:`exits` block ended.

    Attributes:
        status: 0 if it finished, else the command's exit status.
        kept: What a failure leaves (``"nothing was written"``), said after an ``OSError`` or a
            stop; ``None``: nothing is said. The block may change it as it goes.
    """

    status: int = 0
    kept: str | None = None


@contextmanager
def exits(
    command: str, kept: str | None = None,
    stopped: Callable[[str, BaseException], str] | None = None,
) -> Iterator[Exit]:
    """Within the block SIGTERM raises :class:`~imitate.cli.console.Terminated`; a failure ends
    it as ``command``'s one-line error on stderr and its status in the :class:`Exit` yielded:
    ``ImitateError`` and ``OSError`` 1, Ctrl-C 130, SIGTERM 143.

    Args:
        command: The sub-command, as the error line names it.
        kept: The first :attr:`Exit.kept`.
        stopped: The line for a stop, from how it came (``"interrupted (Ctrl-C)"`` or
            ``"terminated (SIGTERM)"``) and its exception; default: how, then what is kept.
    """
    outcome = Exit(kept=kept)
    try:
        with console.terminated_as_exception():
            yield outcome
    except ImitateError as err:
        outcome.status = console.fail(command, _flags(str(err)), 1)
    except OSError as err:  # disk full, no permission
        outcome.status = console.fail(command, _then(str(err), outcome.kept), 1)
    except (KeyboardInterrupt, console.Terminated) as err:
        how, status = ("interrupted (Ctrl-C)", 130) if isinstance(err, KeyboardInterrupt) else (
            "terminated (SIGTERM)", 143
        )
        line = stopped(how, err) if stopped else _then(how, outcome.kept)
        outcome.status = console.fail(command, line, status)


def _then(text: str, kept: str | None) -> str:
    return f"{text}; {kept}" if kept else text


def _flags(message: str) -> str:
    """``message`` with each ``name='value'`` of a parameter in :data:`FLAGS` written as its
    flag and value (``--similarity variance,flat``; an empty value as ``''``)."""
    names = "|".join(FLAGS)
    return re.sub(
        rf"\b({names})=(['\"])(.*?)\2", lambda m: f"{FLAGS[m[1]]} {m[3] or m[2] * 2}", message
    )


def stages_command(args: argparse.Namespace, command_line: str) -> int:
    """``imitate run`` or a stage's sub-command: its stages in the run directory, holding its
    lock; prints the summary."""
    if args.run_dir and args.out and args.run_dir != args.out:
        args.parser.error(f"two run directories given: {args.run_dir} and --out {args.out}; "
                          "give one")
    run_dir = args.out or args.run_dir or DEFAULT_RUN
    names, fresh = stages_of(args.command), starts_run(args.command)
    from imitate.rundir.lock import locked
    from imitate.stages.config import RunConfig, load_config

    progress = _Progress(run_dir)
    with exits(args.command, stopped=progress.stopped) as outcome:
        if fresh and not args.into_existing:
            _refuse_foreign(run_dir)
        with locked(run_dir, command_line, create=fresh):
            from imitate.stages import runner  # the stages: once the directory is ours

            base = RunConfig() if fresh else load_config(run_dir)
            try:
                config = config_for(args, base)
            except ImitateError as err:
                args.parser.error(str(err))
            if fresh:
                _warn_if_replaced(run_dir, config)
            log.debug("run directory %s, settings %s", run_dir, config.to_json())
            report = runner.run_stages(
                names, run_dir, config, force=args.force, starting=progress.start
            )
    if outcome.status:
        return outcome.status
    from imitate.envs.task import get_task  # loaded by the stages

    print(console.summary(report, names, run_dir, get_task(config.task)))
    return 0


class _Progress:
    """The stage running in ``run_dir`` and its manifest as the stages before it left it: what
    a stop tells."""

    def __init__(self, run_dir: Path):
        self.run_dir = run_dir
        self.stage: str | None = None
        self.manifest = _manifest_id(run_dir)

    def start(self, stage: str) -> None:
        """Called as ``stage`` starts: says so, and that it compiles if it does."""
        from imitate import warmup

        self.stage, self.manifest = stage, _manifest_id(self.run_dir)
        log.info("== %s", stage)
        notice = warmup.compile_notice(stage)
        if notice:
            log.info(notice)

    def stopped(self, how: str, err: BaseException) -> str:
        """The line for a stop by ``how``: the stage it cut short, or saved just before."""
        if isinstance(err.__context__, ImitateError):  # the signal came as the stage failed
            return f"{how} as stage {self.stage} failed: {err.__context__}"
        saved = _manifest_id(self.run_dir) != self.manifest
        return console.stopped(how, self.stage, self.run_dir, saved)


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
    try:
        found = os.stat(run_dir / MANIFEST)
    except OSError:
        return None
    return found.st_dev, found.st_ino


def eval_command(args: argparse.Namespace) -> int:
    """``imitate eval`` or ``imitate compare`` of ``args.run_dir`` (of the run's task, which
    ``--task`` must name if given); prints its summary."""
    from imitate import evaluation  # MuJoCo and the planner: once the arguments are fine
    from imitate.envs.task import get_task
    from imitate.evaluation import compare, compare_report

    with exits(args.command, "the finished variations are kept; run it again to go on") as outcome:
        task = get_task(evaluation.run_task(args.run_dir))
        if args.task is not None and args.task != task.name:
            raise ImitateError(
                f"--task {args.task} not accepted: the run in {args.run_dir} is of task "
                f"{task.name!r}; give --task {task.name} or leave it out"
            )
        name, suite = evaluation.named_suite(args.suite, task)
        if args.weight is not None:
            suite = suite.replace(collision_weight=args.weight)
        if args.command == "eval" and args.weighting is not None:
            suite = suite.replace(similarity=args.weighting)
        if args.command == "eval":
            folder = args.out or evaluation.default_out(args.run_dir, name, suite)
        else:
            folder = compare.out_folder(args.run_dir, name, args.levels)
        outcome.kept = f"the finished variations are kept in {folder}; run it again to go on"
        if args.command == "compare":
            sweep = compare.parse_sweep(args.levels, task.name) if args.levels is not None else None
            result = compare.compare(
                args.run_dir, suite, args.weightings.split(","), name=name, n=args.n,
                seed=args.seed, n_teachers=args.teachers, sweep=sweep, workers=args.workers,
                ray=args.ray, confirm=args.confirm, primary=args.primary,
            )
            ran = result["run"]
            text = (f"{compare_report.markdown(result, task)}\n\nran {ran['ran']} variations in "
                    f"{ran['wall_seconds']:.0f} s ({ran['backend']}, workers "
                    f"{ran['workers']}); results: {folder}")
        else:
            summary = evaluation.evaluate(
                args.run_dir, suite, n=args.n, seed=args.seed, n_teachers=args.teachers,
                workers=args.workers, ray=args.ray, videos=args.videos, out=folder,
            )
            text = evaluation.text(summary, folder, task)
    if outcome.status:
        return outcome.status
    print(text)
    return 0


def sensitivity_command(args: argparse.Namespace) -> int:
    """``imitate sensitivity`` of ``args.run_dir``: measures its teachers' tolerance and prints
    the table (and, ``--against``, the alignments beside a comparison)."""
    from imitate.envs.task import get_task
    from imitate.evaluation import run_task, sensitivity, sensitivity_run
    from imitate.rundir.artifacts import load_json

    with exits(args.command, "the teachers measured are kept; run it again to go on") as outcome:
        compared = None if args.against is None else load_json(args.against)
        try:
            magnitudes = [float(k) for k in args.magnitudes.split(",")]
        except ValueError:
            raise ImitateError(f"--magnitudes {args.magnitudes!r} not accepted: numbers, "
                               "comma-separated, e.g. 1,2,4") from None
        results = sensitivity_run.measure(
            args.run_dir, args.teachers, args.confirm,
            (os.cpu_count() or 1) if args.workers is None else args.workers,
            magnitudes, args.seeds,
        )
        text = sensitivity_run.report(results, get_task(run_task(args.run_dir)), args.seeds)
        if compared is not None:
            text += "\n\n" + sensitivity_run.predict(results, compared)
        folder = sensitivity.results_folder(args.run_dir)
        text += f"\n\nresults: {folder} (figure: {sensitivity_run.FIGURE})"
    if outcome.status:
        return outcome.status
    print(text)
    return 0


def export_command(args: argparse.Namespace) -> int:
    """``imitate export``: writes the datasets, prints where."""
    from imitate.export import export as write

    with exits("export", "nothing was written") as outcome:
        out = write(args.run_dir, args.format, args.out, images=args.images,
                    from_eval=args.from_eval)
    if outcome.status:
        return outcome.status
    print(out)
    return 0
