"""The tasks by name, light to import: each is a package ``imitate.envs.<name>`` with an
``options`` module (its own run settings, read by the command line's help without MuJoCo), a
``teacher`` module (its demonstrations' :class:`~imitate.envs.teacher_motion.Script`,
``SCRIPT``, and ``demonstrated(motion, demo)``: whether a demonstration does the task in
physics) and a ``task`` module (its :class:`~imitate.envs.task.Task`, ``TASK``, which
:func:`imitate.envs.task.get_task` imports). :data:`NAMES` are found, not listed: every package
of ``imitate.envs`` with these three modules is a task (:func:`found`).
"""

from __future__ import annotations

import importlib
import math
import pkgutil
from collections.abc import Mapping
from dataclasses import dataclass
from numbers import Real
from pathlib import Path
from typing import Any

from imitate.errors import ImitateError, quoted

__all__ = ["DEFAULT", "NAMES", "PARTS", "Option", "check", "folder", "found", "module",
           "options", "settings"]

PARTS = ("options", "teacher", "task")  # the modules that make a package of envs a task
DEFAULT = "pour"


def found(folder: Path = Path(__file__).parent) -> tuple[str, ...]:
    """The tasks in ``folder`` (``imitate.envs``'s): its packages with every module of
    :data:`PARTS`, :data:`DEFAULT` first, the others by name; nothing imported."""
    names = sorted(
        info.name for info in pkgutil.iter_modules([str(folder)])
        if info.ispkg and all((folder / info.name / f"{part}.py").is_file() for part in PARTS)
    )
    return tuple(sorted(names, key=lambda name: name != DEFAULT))


NAMES = found()


@dataclass(frozen=True)
class Option:
    """One of a task's own run settings (a flag of ``imitate run``, a key of its suites).

    Attributes:
        default: Its value unless set.
        help: What it is, with its unit.
        low, high: Accepted range, inclusive.
        integer: Whether it is a whole number.
        stage: The stage that first uses it.
        quick: Its value in a quick run (``RunConfig.quick``); ``None``: the default.
        suite: Its range ``(low, high)`` in the built-in evaluation suite, drawn uniformly;
            ``None``: the whole accepted range.
    """

    default: float
    help: str
    low: float
    high: float
    integer: bool = False
    stage: str = "optimize"
    quick: float | None = None
    suite: tuple[float, float] | None = None


    def value(self, name: str, value: Any) -> float:
        """``value`` as this setting's type (``int`` or ``float``).

        Raises:
            ImitateError: naming ``name``, ``value`` and what is accepted, unless it is a number
                in range (a whole one if ``integer``).
        """
        number = float(value) if isinstance(value, Real) and not isinstance(value, bool) else None
        if (number is None or not math.isfinite(number) or not self.low <= number <= self.high
                or (self.integer and not number.is_integer())):
            kind = "a whole number" if self.integer else "a number"
            raise ImitateError(
                f"{name}={quoted(value)} not accepted: {kind} in {self.low:g}..{self.high:g}"
            )
        return int(number) if self.integer else number


def check(name: str) -> None:
    """Raise ``ImitateError`` unless ``name`` is a task's."""
    if name not in NAMES:
        raise ImitateError(f"task {quoted(name)} unknown; accepted: {list(NAMES)}")


def folder(name: str) -> Path:
    """The folder of task ``name``'s package."""
    check(name)
    return Path(__file__).parent / name


def module(name: str, part: str):
    """The module ``part`` (``"options"``, ``"teacher"``, ``"task"``) of task ``name``."""
    check(name)
    return importlib.import_module(f"imitate.envs.{name}.{part}")


def options(name: str) -> dict[str, Option]:
    """The task ``name``'s own run settings by name, in order (light: no MuJoCo)."""
    return module(name, "options").OPTIONS


def settings(name: str, given: Mapping[str, Any] | None = None) -> dict[str, float]:
    """Task ``name``'s own settings: ``given`` checked, with the defaults of those not given, in
    the task's order.

    Raises:
        ImitateError: a name not of the task's (with its flag), or a value out of its range.
    """
    declared = options(name)
    given = dict(given or {})
    unknown = sorted(set(given) - set(declared))
    if unknown:
        shown = ", ".join(f"{n} (--{n.replace('_', '-')})" for n in unknown)
        raise ImitateError(f"{shown} not a setting of task {name!r}; its own: {list(declared)}")
    return {n: o.value(n, given.get(n, o.default)) for n, o in declared.items()}
