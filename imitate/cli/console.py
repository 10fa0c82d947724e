"""The ``imitate`` command's terminal: the library's log on stderr (``-q``, ``-v``), SIGTERM
unwinding like Ctrl-C, one-line errors, and the run's summary on stdout.

Progress goes to stderr through :mod:`logging` (the ``imitate`` logger, configured here only).
Before a sub-command loads MuJoCo, the kernels and matplotlib, :func:`prepare` keeps what the
library logs meanwhile for :func:`log_to_stderr`, makes MuJoCo render headless (see
:func:`imitate.envs.rendering.import_mujoco`) and matplotlib draw with Agg.
"""

from __future__ import annotations

import atexit
import logging
import logging.handlers
import os
import re
import shutil
import signal
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from imitate.errors import shortened
from imitate.rundir.layout import PAGE

if TYPE_CHECKING:  # the task's package loads MuJoCo: not for `imitate --help`
    from imitate.envs.task import Task

__all__ = [
    "Terminated", "fail", "log_to_stderr", "prepare", "stopped", "summary",
    "terminated_as_exception",
]


def _matplotlib_config_dir() -> None:
    """``MPLCONFIGDIR`` in a temporary folder, removed at exit, when matplotlib's default
    (``$XDG_CONFIG_HOME/matplotlib`` or ``~/.config/matplotlib``) is not writable, as under a
    read-only home, where matplotlib would warn about it on every run."""
    if os.environ.get("MPLCONFIGDIR"):
        return
    config = Path(os.environ.get("XDG_CONFIG_HOME") or Path.home() / ".config", "matplotlib")
    try:
        config.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=config).close()
    except OSError:
        os.environ["MPLCONFIGDIR"] = tempfile.mkdtemp(prefix="imitate-matplotlib-")
        atexit.register(shutil.rmtree, os.environ["MPLCONFIGDIR"], ignore_errors=True)


# What the library logs while MuJoCo and the kernels load (numba's cache moved) waits here for
# -v/-q (see log_to_stderr).
_LOADING = logging.handlers.BufferingHandler(capacity=1000)


def prepare() -> None:
    """Before a sub-command loads MuJoCo, the kernels and matplotlib: buffer the library's log,
    render headless (:func:`imitate.envs.rendering.import_mujoco`), draw with Agg. Once."""
    logger = logging.getLogger("imitate")
    if _LOADING in logger.handlers:
        return
    logger.addHandler(_LOADING)
    logger.setLevel(logging.DEBUG)
    from imitate.envs import rendering

    rendering.import_mujoco()
    _matplotlib_config_dir()
    import matplotlib

    matplotlib.use("Agg")


class _Lines(logging.Formatter):
    """A record as its message; a debug line, warning or error prefixed with its level."""

    def format(self, record: logging.LogRecord) -> str:
        text = super().format(record)
        return text if record.levelno == logging.INFO else f"{record.levelname.lower()}: {text}"


class _Stderr(logging.Handler):
    """Writes to the ``sys.stderr`` of the moment (tests replace it)."""

    def emit(self, record: logging.LogRecord) -> None:
        try:
            print(self.format(record), file=sys.stderr, flush=True)
        except Exception:
            self.handleError(record)


_STDERR = _Stderr()
_STDERR.setFormatter(_Lines())


def log_to_stderr(level: int) -> None:
    """The ``imitate`` logger's records from ``level`` up on stderr, those kept while the
    library loaded first."""
    logger = logging.getLogger("imitate")
    logger.removeHandler(_LOADING)
    logger.addHandler(_STDERR)
    logger.setLevel(level)
    for record in _LOADING.buffer:
        if record.levelno >= level:
            _STDERR.handle(record)
    _LOADING.buffer.clear()


class Terminated(BaseException):
    """SIGTERM arrived; unwinds like Ctrl-C, so that temporary files and child processes go."""


@contextmanager
def terminated_as_exception() -> Iterator[None]:
    """Within the block, SIGTERM raises :class:`Terminated` (in the main thread)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum, frame):
        raise Terminated

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def stopped(how: str, stage: str | None, run_dir: Path, saved: bool = False) -> str:
    """What a command stopped by ``how`` in ``stage`` left in ``run_dir``: nothing of the
    stage, or all of it if ``saved`` (the signal came during or after its commit, which it
    waited for)."""
    if stage is None:
        return f"{how} before any stage ran"
    if saved:
        return f"{how} just after stage {stage} was saved in {run_dir}"
    return f"{how} in stage {stage}, which changed nothing in {run_dir}"


def fail(command: str, message: str, status: int) -> int:
    """Print ``message`` as the command's one-line error, its line breaks joined by a space
    (other spaces kept: a path's two spaces stay two), its long words cut
    (:func:`~imitate.errors.shortened`); returns ``status``."""
    line = shortened(re.sub(r"[ \t]*[\r\n]+[ \t]*", " ", message.strip()))
    print(f"imitate {command}: error: {line}", file=sys.stderr)
    return status


def summary(report: dict, stages: tuple[str, ...], run_dir: Path, task: Task) -> str:
    """The stage-timing table and the headline numbers of ``report``, those of the run's
    ``task`` among them (its critical phase's error, its measures)."""
    lines = ["", f"{'stage':<10} {'seconds':>8}"]
    timings = report.get("timings", {})
    lines += [f"{stage:<10} {timings[stage]:8.1f}" for stage in stages]
    lines.append(f"{'total':<10} {sum(timings[s] for s in stages):8.1f}")
    headline = {
        "demos": ("detected", "expected"),
        "perception": ("pos_err_mm_median", "pos_err_mm_p95", "angle_err_deg_median"),
        "learning": ("bic", "n_components", "n_components_fast_bic", "n_components_full_bic"),
        "optimization": (
            "min_distance_m", *task.error_keys,
        ),
        "replay": (*task.measures, "min_distance_m", "success"),
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
    lines.append(f"page: {run_dir / PAGE}")
    return "\n".join(lines)


def _fmt(value) -> str:
    return f"{value:.4g}" if isinstance(value, float) else str(value)
