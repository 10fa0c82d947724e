"""The ``imitate`` command: one sub-command per stage of a run, and ``run`` for all of them.

    imitate run --out runs/latest             # watch, learn, optimize, replay, plot
    imitate run --task insert --out runs/insert  # the second task
    imitate run --quick --out runs/quick      # small images, 3 demonstrations: under a minute
    imitate optimize runs/latest --collision-weight 30   # re-plan with the learned model
    imitate replay runs/latest && imitate figures runs/latest
    imitate sensitivity runs/latest --teachers 3   # what the task tolerates, per teacher

Each stage reads the previous stage's artifacts in the run directory (see
:mod:`imitate.stages.table`); settings given on the command line replace those in its
``config.json``, the rest are kept. One command at a time holds a run directory (see
:mod:`imitate.rundir`); a stage refuses inputs that are stale or from another run unless
``--force`` (see :mod:`imitate.stages.provenance`); ``run`` and ``observe`` start a run only in a
new or empty folder or a run directory (``--into-existing``: in another folder). Errors are one
line on stderr: exit status 1, 2 for a bad flag, 130 for Ctrl-C and 143 for SIGTERM (see
:mod:`imitate.cli.commands`); a stage that does not finish changes nothing.

Progress goes to stderr (``-q`` leaves warnings and errors, ``-v`` adds debug lines; see
:mod:`imitate.cli.console`). The command line (:mod:`imitate.cli.parser`) is built for the
sub-command given only, from plain constants: no ``--help`` loads MuJoCo, numba, SciPy or
matplotlib.
"""

from __future__ import annotations

import sys

from imitate.cli import commands, console
from imitate.cli.parser import COMMANDS, build_parser, unrecognized

__all__ = ["main"]


def main(argv: list[str] | None = None) -> int:
    """The ``imitate`` command with ``argv`` (default: the process's arguments); returns its
    exit status (a bad flag exits with status 2)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args, unknown = build_parser(full=[a for a in argv if a in COMMANDS][:1]).parse_known_args(argv)
    if unknown:
        args.parser.error(unrecognized(unknown, args.parser))
    console.prepare()
    console.log_to_stderr(args.log_level)
    if args.command == "export":
        return commands.export_command(args)
    if args.command in ("eval", "compare"):
        return commands.eval_command(args)
    if args.command == "sensitivity":
        return commands.sensitivity_command(args)
    return commands.stages_command(args, " ".join(["imitate", *argv]))
