"""The tasks by name, light to import: each is a package ``imitate.envs.<name>`` with an
``options`` module (its own run settings, read by the command line's help without MuJoCo), a
``teacher`` module (its demonstrations' :class:`~imitate.envs.teacher_motion.Script`,
``SCRIPT``) and a ``task`` module (its :class:`~imitate.envs.task.Task`, ``TASK``, which
:func:`imitate.envs.task.get_task` imports).
"""

from __future__ import annotations

import importlib
import math
from dataclasses import dataclass
from typing import Any

from imitate.errors import ImitateError

__all__ = ["DEFAULT", "NAMES", "Option", "check", "module", "options"]

NAMES = ("pour", "insert")
DEFAULT = "pour"


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
        if (isinstance(value, bool) or not isinstance(value, int | float)
                or not math.isfinite(value) or not self.low <= value <= self.high
                or (self.integer and value != int(value))):
            kind = "a whole number" if self.integer else "a number"
            raise ImitateError(
                f"{name}={value!r} not accepted: {kind} in {self.low:g}..{self.high:g}"
            )
        return int(value) if self.integer else float(value)


def check(name: str) -> None:
    """Raise ``ImitateError`` unless ``name`` is a task's."""
    if name not in NAMES:
        raise ImitateError(f"task {name!r} unknown; accepted: {list(NAMES)}")


def module(name: str, part: str):
    """The module ``part`` (``"options"``, ``"teacher"``, ``"task"``) of task ``name``."""
    check(name)
    return importlib.import_module(f"imitate.envs.{name}.{part}")


def options(name: str) -> dict[str, Option]:
    """The task ``name``'s own run settings by name, in order (light: no MuJoCo)."""
    return module(name, "options").OPTIONS
