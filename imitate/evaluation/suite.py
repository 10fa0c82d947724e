"""The evaluation suite: the distribution the variations of ``imitate eval`` are drawn from.

A suite is of one task. It is a TOML or JSON file of top-level keys, each optional (the
built-in default suite fills the rest); :data:`KEYS` declares every key that is no task's once
with its default, range and meaning, and :func:`keys` adds a range key per setting of the task's
own (:func:`imitate.envs.tasks.options`). A range key takes ``[low, high]`` (drawn uniformly) or
one number (fixed), a switch ``true`` or ``false``. Unknown keys, out-of-range values,
``low > high`` and an empty file are refused with an ``ImitateError`` naming the entry. The
named suites are the built-in default and the files in the task's ``suites`` folder.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from imitate.defaults import (  # plain constants: `imitate eval --help` shows KEYS quickly
    COLLISION_WEIGHT,
    MAX_ITER,
    MAX_WEIGHT,
    NULLSPACE_PUSH,
    OBSTACLE_SHAPES,
    PATH_LENGTH_WEIGHT,
    SIMILARITIES,
    SIMILARITY,
    TABLE_X,
    TABLE_Y,
)
from imitate.envs import tasks
from imitate.errors import ImitateError, quoted

if TYPE_CHECKING:  # the task's package loads MuJoCo: not for `imitate eval --help`
    from imitate.envs.task import Task

__all__ = ["KEYS", "Key", "Suite", "keys", "load_suite", "named_suite", "suite_names"]


@dataclass(frozen=True)
class Key:
    """One suite key: its default, what it accepts and what it means.

    Attributes:
        default: The default suite's value; a ``(low, high)`` tuple for a range key.
        help: What it is, with its unit.
        low, high: Accepted values (each end of a range), inclusive.
        integer: Whole numbers only.
        choices: The accepted names: of a list of names, or of one name (a ``str`` default).

    A ``bool`` default makes a switch: ``true`` or ``false`` only.
    """

    default: Any
    help: str
    low: float = 0.0
    high: float = float("inf")
    integer: bool = False
    choices: tuple[str, ...] | None = None

    @property
    def is_range(self) -> bool:
        return isinstance(self.default, tuple) and self.choices is None

    @property
    def is_name(self) -> bool:
        return isinstance(self.default, str)

    @property
    def is_switch(self) -> bool:
        return isinstance(self.default, bool)

    def accepted(self) -> str:
        """What the key accepts, in words."""
        if self.is_name:
            return f"one of {list(self.choices or ())}"
        if self.is_switch:
            return "true or false"
        if self.choices is not None:
            return f"a non-empty list of {list(self.choices)}"
        kind = "whole numbers" if self.integer else "numbers"
        bounds = f"{self.low:g}..{self.high:g}" if self.high != float("inf") else f">= {self.low:g}"
        if self.is_range:
            return f"[low, high] or one value, {kind} in {bounds}"
        return f"{'a whole number' if self.integer else 'a number'} in {bounds}"

    def check(self, name: str, value: Any, source: str = "suite") -> Any:
        """``value`` as the suite stores it (a range as a ``(low, high)`` tuple of floats or
        ints).

        Raises:
            ImitateError: naming ``source``, ``name``, ``value`` and what is accepted.
        """
        refused = f"{source}: entry {name}={quoted(value)} not accepted: {self.accepted()}"
        if self.is_name:
            if not isinstance(value, str) or value not in (self.choices or ()):
                raise ImitateError(refused)
            return value
        if self.is_switch:
            if not isinstance(value, bool):
                raise ImitateError(refused)
            return value
        if self.choices is not None:
            if (
                not isinstance(value, list)
                or not value
                or any(v not in self.choices for v in value)
            ):
                raise ImitateError(refused)
            return tuple(dict.fromkeys(value))
        values = value if self.is_range and isinstance(value, list) else [value]
        if (
            (self.is_range and len(values) not in (1, 2))
            or (not self.is_range and isinstance(value, list))
            or not all(self._number(v) for v in values)
            or values[0] > values[-1]
        ):
            raise ImitateError(refused)
        kind = int if self.integer else float
        if self.is_range:
            return kind(values[0]), kind(values[-1])
        return kind(values[0])

    def _number(self, v: Any) -> bool:
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
            return False
        if self.integer and v != int(v):
            return False
        return self.low <= v <= self.high


KEYS: dict[str, Key] = {
    "variations": Key(100, "variations drawn when --n is not given", 1, 100_000, integer=True),
    "collision_weight": Key(COLLISION_WEIGHT, "weight of the collision cost", high=MAX_WEIGHT),
    "similarity": Key(
        SIMILARITY, "how the similarity cost weights the task over time (the run "
        "setting of the same name)", choices=SIMILARITIES,
    ),
    "path_length_weight": Key(
        (PATH_LENGTH_WEIGHT,) * 2, "weight of the joint path-length cost (raised, "
        "it competes with the task everywhere)", 0, 1e3,
    ),
    "max_iter": Key(MAX_ITER, "optimizer iteration limit", 1, 10_000, integer=True),
    "nullspace_push": Key(
        NULLSPACE_PUSH, "whether the planner may push a plan that keeps less than its "
        "margin once more through the task's null space (the default planner); false: the "
        "attractors alone, as in the paper",
    ),
    "limit_margin": Key(
        0.0, "the planner keeps every joint this far inside its range at each end (never past "
        "the rest pose) [rad]", 0.0, 0.3,
    ),
    "replays": Key(
        3, "physics replays per variation, each from its own seed of the initial-state noise "
        "(joint angles +-0.01 rad, and the task's own)", 1, 20, integer=True,
    ),
    "obstacle_share": Key(0.9, "share of variations with one obstacle on the table", 0, 1),
    "in_path_share": Key(
        0.5, "share of the obstacles placed in the path of the held objects (their plan at "
        "collision weight 0), the others at random", 0, 1,
    ),
    "shapes": Key(OBSTACLE_SHAPES, "obstacle shapes, drawn uniformly", choices=OBSTACLE_SHAPES),
    "obstacle_x": Key((0.40, 0.75), "centre x of an obstacle placed at random [m]", *TABLE_X),
    "obstacle_y": Key((-0.35, 0.35), "centre y of an obstacle placed at random [m]", *TABLE_Y),
    "obstacle_size": Key(
        (0.015, 0.05), "an obstacle's half width: each half extent of a box's footprint, a "
        "cylinder's radius [m]", 0.005, 0.2,
    ),
    "obstacle_half_height": Key(
        (0.02, 0.10), "half height of an obstacle placed at random (it stands on the table) [m]",
        0.005, 0.3,
    ),
    "path_overlap": Key(
        (0.005, 0.03), "how far an obstacle in the path rises above the bottom of the held "
        "object it stands under [m]", 0.0, 0.2,
    ),
    "shelf_share": Key(
        0.0, "share of variations with a shelf (a fixture off the table) over the tool in the "
        "task's critical phase, placed from the path at collision weight 0", 0, 1,
    ),
    "shelf_gap": Key(
        (0.02, 0.10), "how far a shelf's underside reaches below the tool's highest point in "
        "the critical phase at collision weight 0 [m]", 0.0, 0.3,
    ),
    "plate_share": Key(
        0.0, "share of variations with a plate (a fixture off the table) under the target in "
        "the critical phase, placed from the path at collision weight 0", 0, 1,
    ),
    "plate_gap": Key(
        (-0.01, 0.0), "how far a plate's top rises above the target's lowest point in the "
        "critical phase at collision weight 0 [m] (below it, if negative)", -0.1, 0.1,
    ),
    "friction_scale": Key(
        (0.8, 1.25), "factor on every geom's sliding friction in physics", 0.1, 10
    ),
    "damping_scale": Key((0.8, 1.25), "factor on the robot's joint damping in physics", 0.1, 10),
    "mass_scale": Key(
        (0.8, 1.25), "factor on the masses and inertias of the bodies that move freely (the "
        "held objects and what they carry) in physics", 0.1, 10,
    ),
}
_PHYSICS = ("friction_scale", "damping_scale", "mass_scale")  # the task's keys come before


def keys(task: str) -> dict[str, Key]:
    """The keys of a suite of ``task`` (a name of ``imitate.envs.tasks.NAMES``): :data:`KEYS`
    with a range key per setting of the task's own before the physics perturbations, its range
    the option's ``suite`` (else all it accepts)."""
    own = {
        name: Key(
            option.suite or (option.low, option.high), option.help, option.low, option.high,
            integer=option.integer,
        )
        for name, option in tasks.options(task).items()
    }
    rest = {name: key for name, key in KEYS.items() if name not in _PHYSICS}
    return {**rest, **own, **{name: KEYS[name] for name in _PHYSICS}}


@dataclass(frozen=True)
class Suite:
    """A suite of a task: one value per entry of its :func:`keys` (ranges as ``(low, high)``).

    Attributes:
        values: The values by key.
        task: The task's name (``imitate.envs.tasks.NAMES``).
    """

    values: dict[str, Any]
    task: str = tasks.DEFAULT

    @classmethod
    def default(cls, task: str = tasks.DEFAULT) -> Suite:
        """The built-in suite of ``task``."""
        return cls({name: key.default for name, key in keys(task).items()}, task)

    @classmethod
    def from_dict(
        cls, entries: dict[str, Any], source: str = "suite", task: str = tasks.DEFAULT
    ) -> Suite:
        """The default suite of ``task`` with ``entries`` replacing its values.

        Raises:
            ImitateError: an empty ``entries``, an unknown key or a value out of range.
        """
        accepted = keys(task)
        if not isinstance(entries, dict) or not entries:
            raise ImitateError(
                f"{source} is empty: give at least one of the keys {sorted(accepted)}"
            )
        unknown = sorted(set(entries) - set(accepted))
        if unknown:
            raise ImitateError(
                f"{source}: unknown entry {unknown[0]!r}; accepted for task {task!r}: "
                f"{sorted(accepted)}"
            )
        values = dict(cls.default(task).values)
        for name, value in entries.items():
            values[name] = accepted[name].check(name, value, source)
        return cls(values, task)

    def replace(self, **changes: Any) -> Suite:
        """This suite with some values changed (checked like a file's)."""
        return Suite.from_dict({**self.to_json(), **changes}, task=self.task)

    def __getitem__(self, name: str) -> Any:
        return self.values[name]

    def to_json(self) -> dict[str, Any]:
        """The values as a file would give them (ranges as lists)."""
        return {k: list(v) if isinstance(v, tuple) else v for k, v in self.values.items()}

    def digest(self, seed: int, teacher: int, model: bytes, code: str) -> str:
        """Identifies the results of the variations this suite draws: sha256 (16 hex digits) of
        its task and values (but ``variations``: a longer evaluation extends a shorter one),
        ``seed``, the ``teacher``'s seed and its learned model's bytes and ``code``
        (:func:`imitate.stages.provenance.code_digest`: records made by other code are not
        reused)."""
        values = {k: v for k, v in self.to_json().items() if k != "variations"}
        text = json.dumps({"task": self.task, "suite": values, "seed": seed, "teacher": teacher,
                           "code": code}, sort_keys=True)
        return hashlib.sha256(text.encode() + hashlib.sha256(model).digest()).hexdigest()[:16]


def suite_names(task: Task) -> tuple[str, ...]:
    """The suites ``--suite NAME`` takes for ``task``: the built-in default and the files in the
    task's ``suites`` folder."""
    return ("default", *sorted(p.stem for p in task.suites.glob("*.toml")))


def named_suite(text: str | None, task: Task) -> tuple[str, Suite]:
    """The suite of ``task`` that ``--suite`` names, and its name: ``None`` or ``default`` for
    the built-in one, a name of :func:`suite_names`, or a ``.toml`` or ``.json`` file (named by
    its stem, :func:`file_name`).

    Raises:
        ImitateError: as :func:`load_suite`, or a name that is not shipped.
    """
    if text is None or text == "default":
        return "default", Suite.default(task.name)
    names = suite_names(task)
    if text in names:
        return text, load_suite(task.suites / f"{text}.toml", task.name)
    path = Path(text)
    if path.suffix not in (".toml", ".json"):
        raise ImitateError(
            f"--suite {text} not accepted: one of {', '.join(names)}, or a .toml or .json file"
        )
    return file_name(path), load_suite(path, task.name)


def file_name(path: Path) -> str:
    """The name a suite file gives its results' folder, figures and tables: its stem with every
    character but letters, digits, ``_`` and ``-`` made ``_`` (no HTML, no mathtext, no folder
    above: ``...toml`` is ``__``)."""
    return re.sub(r"[^A-Za-z0-9_-]", "_", Path(path).stem) or "_"


def load_suite(path: Path, task: str = tasks.DEFAULT) -> Suite:
    """The suite of ``task`` in ``path`` (``.toml`` or ``.json``).

    Raises:
        ImitateError: an unreadable file, another format, or bad entries (see :class:`Suite`).
    """
    path = Path(path)
    if path.suffix not in (".toml", ".json"):
        raise ImitateError(f"suite {path} not accepted: a .toml or .json file")
    from imitate.rundir.artifacts import check_regular  # numpy: not for --help's keys

    check_regular(path)
    try:
        text = path.read_text()
    except OSError as err:
        raise ImitateError(f"suite {path} cannot be read: {err.strerror}") from None
    except UnicodeDecodeError:
        raise ImitateError(f"suite {path} not accepted: it is not UTF-8 text") from None
    if path.suffix == ".json":
        try:
            entries = json.loads(text) if text.strip() else {}
        except (json.JSONDecodeError, RecursionError) as err:
            raise ImitateError(f"suite {path} is not valid JSON: {err}") from None
    else:
        import tomllib  # Python 3.11 and later

        try:
            entries = tomllib.loads(text)
        except (tomllib.TOMLDecodeError, RecursionError) as err:
            raise ImitateError(f"suite {path} is not valid TOML: {err}") from None
    return Suite.from_dict(entries, f"suite {path}", task)
