"""The settings of a run (``config.json``): one declaration per setting.

Each field of :class:`RunConfig` carries a :class:`Setting` (what it is, its range, its stage and
flag); the checks, the command-line flags with their help and the class's documentation are
derived from these.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from imitate import defaults
from imitate.envs import tasks
from imitate.errors import ImitateError, quoted, shell_word
from imitate.rundir.artifacts import load_json
from imitate.stages import table

if TYPE_CHECKING:  # loaded on use: the command line's help reads the declarations only
    from imitate.envs import assembly
    from imitate.envs.task import Task
    from imitate.envs.teacher_motion import TeacherConfig
    from imitate.motion import PlanConfig

__all__ = ["RunConfig", "Setting", "load_config", "parse_obstacle", "settings"]


@dataclass(frozen=True)
class Setting:
    """What one field of :class:`RunConfig` means, what it accepts and where it is set.

    Attributes:
        help: What it is, with its unit; the flag's help and the documentation.
        stage: The stage that first uses it; its sub-command (and ``run``) takes the flag.
            ``None``: a setting of the whole run, taken by every sub-command.
        flag: Its command-line flag; ``None``: set in ``config.json`` only.
        low, high: Accepted range, inclusive; ``None``: unbounded on that side. A value with a
            bound must be finite; a tuple value needs one or more elements, each in range.
        multiple: The value must be a multiple of this; ``None``: any value in range.
        choices: The accepted values.
        parse: Reads the flag's text (raising ``ImitateError``); ``None``: the field's type.
        metavar: The flag's value in the help; ``None``: the type's name in capitals.
    """

    help: str
    stage: str | None = None
    flag: str | None = None
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] | None = None
    multiple: int | None = None
    parse: Callable[[str], Any] | None = None
    metavar: str | None = None

    def bounds(self) -> str:
        """The range in short (``"2..20"``, ``">= 0"``, ``"64..1920, a multiple of 8"``), or
        ``""`` if unbounded."""
        if self.low is not None and self.high is not None:
            text = f"{self.low:g}..{self.high:g}"
        else:
            text = f">= {self.low:g}" if self.low is not None else ""
        return f"{text}, a multiple of {self.multiple}" if self.multiple else text

    def check(self, name: str, value: Any) -> None:
        """Raises ``ImitateError`` naming ``name``, ``value`` and what is accepted, unless
        ``value`` is accepted."""
        if self.choices is not None and value not in self.choices:
            raise ImitateError(f"{name}={quoted(value)} not accepted: one of {self.choices}")
        if self.low is None and self.high is None:
            return
        values = value if isinstance(value, tuple) else (value,)
        if values and all(self._accepts(v) for v in values):
            return
        if isinstance(value, tuple):
            accepted = f"one or more finite values {self.bounds()}"
        elif self.high is None:
            accepted = f"a finite value {self.bounds()}"
        else:
            accepted = f"a value in {self.bounds()}"
        raise ImitateError(f"{name}={quoted(value)} not accepted: {accepted}{self._nearest(value)}")

    def describe(self, default: Any) -> str:
        """The help with the range and the default: ``"camera rate [Hz], 5..120 (default 30)"``."""
        text = ", ".join(part for part in (self.help, self.bounds()) if part)
        if isinstance(default, bool):
            assert self.flag is not None  # a boolean setting is a flag pair --x / --no-x
            return f"{text} (default --{'' if default else 'no-'}{self.flag.removeprefix('--')})"
        if default is None:
            return text
        shown = f"{default:g}" if _is_number(default) else default
        return f"{text} (default {shown})"

    def _accepts(self, v: Any) -> bool:
        return self._in_range(v) and (self.multiple is None or v % self.multiple == 0)

    def _in_range(self, v: Any) -> bool:
        return bool(
            (isinstance(v, int | np.integer) or np.isfinite(v))  # an int may exceed a float
            and (self.low is None or v >= self.low)
            and (self.high is None or v <= self.high)
        )

    def _nearest(self, value: Any) -> str:
        """``" (nearest: 64, 72)"``: the accepted multiples next to a value in range."""
        if self.multiple is None or not self._in_range(value):
            return ""
        below = value // self.multiple * self.multiple
        nearest = [v for v in (below, below + self.multiple) if self._accepts(v)]
        return f" (nearest: {', '.join(str(v) for v in nearest)})"


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _setting(default: Any, help: str, **declaration: Any) -> Any:
    """A :class:`RunConfig` field with its :class:`Setting`."""
    return field(default=default, metadata={"setting": Setting(help, **declaration)})


# Video sizes are multiples of the encoder's macro block [px] (``envs/video.py``'s
# ``write_video``): others would be padded up to one.
VIDEO_BLOCK = 8
# ``--task-space`` words; anything else names relations (imitate.demos.space_selection.named).
TASK_SPACES = ("declared", "auto", "tpgmm")

_OBSTACLE_FORMS = (
    "box:X,Y,Z:SX,SY,SZ (centre, half extents [m]), cylinder:X,Y,Z:R,H (centre, radius, half "
    "height [m]) or none"
)


def parse_obstacle(text: str) -> assembly.Obstacle | None:
    """The obstacle written in one of the forms ``--obstacle`` takes; ``None`` for ``none``.

    Raises:
        ImitateError: another form, or an obstacle off the table.
    """
    from imitate.envs import assembly

    if text.lower() == "none":
        return None
    try:
        shape, pos, size = text.split(":")
        values: dict[str, Any] = {
            "shape": shape,
            "pos": tuple(float(v) for v in pos.split(",")),
            "size": tuple(float(v) for v in size.split(",")),
        }
    except ValueError:
        raise ImitateError(
            f"{text!r} not accepted: {_OBSTACLE_FORMS}, e.g. box:0.55,0.0,0.70:0.03,0.03,0.05"
        ) from None
    return assembly.Obstacle(**values)


@dataclass(frozen=True)
class RunConfig:
    """Everything a run depends on; stored as ``config.json`` in the run directory.

    The settings, each with its range, default, stage and flag, are listed below (generated
    from the fields' :class:`Setting`).
    """

    seed: int = _setting(0, "seed of the whole run", flag="--seed", metavar="N", low=0)
    task: str = _setting(
        tasks.DEFAULT, "the task the teacher demonstrates and the robot reproduces",
        stage="observe", flag="--task", choices=tasks.NAMES,
    )
    n_demos: int = _setting(
        5, "demonstrations the teacher shows", stage="observe", flag="--demos", low=2, high=20
    )
    width: int = _setting(
        640, "head-camera image width [px]", stage="observe", flag="--width", low=64, high=1920
    )
    height: int = _setting(
        480, "head-camera image height [px]", stage="observe", flag="--height", low=48, high=1080
    )
    fps: float = _setting(30.0, "camera rate [Hz]", stage="observe", flag="--fps", low=5, high=120)
    teacher_variation: str = _setting(
        defaults.TEACHER_VARIATION, "where the teacher's demonstrations vary: aligned (by "
        "centimetres away from the task's critical phase, by millimetres in it: low variance "
        "where the task is, as the paper assumes), misaligned (the rest the same every time, "
        "the critical phase's position spread by centimetres: low variance where the task is "
        "not, a test of that premise), misleading (as aligned, the critical phase also "
        "spread along a direction the task tolerates only while nothing pulls along it) or "
        "coupled (as aligned, in the critical phase both objects moved together by "
        "centimetres: only their difference invariant)",
        stage="observe", flag="--teacher-variation",
        choices=defaults.TEACHER_VARIATIONS,
    )
    k_max: int = _setting(
        30, "largest number of GMM components tried", stage="learn", flag="--k-max", low=1,
        high=50,
    )
    smoothing: float = _setting(
        defaults.SMOOTHING, "Savitzky-Golay window over the tracks before learning [s]",
        stage="learn", flag="--smoothing", low=0, high=1,
    )
    bic: str = _setting(
        defaults.DEFAULT_BIC, "choose the number of components by the full BIC (EM for every "
        "K) or the paper's fast K-means heuristic", stage="learn", flag="--bic",
        choices=defaults.BIC_METHODS,
    )
    oracle: bool = _setting(
        False, "learn from ground-truth poses instead of perception", stage="learn",
        flag="--oracle",
    )
    task_space: str = _setting(
        "declared", "the task space learned in: the task's declared one, the one the "
        "demonstrations' statistics select (auto: each relation's invariance where the task is "
        "decided, imitate.demos.space_selection), every candidate frame at once, reproduced "
        "by the product of their Gaussians in each scene (tpgmm, imitate.learning.tpgmm), or "
        "relations named OF-TO joined by + with eq. 1's angles (tool-target: eq. 1; "
        "tool-target+target-marker)", stage="learn", flag="--task-space",
    )
    collision_weight: float = _setting(
        defaults.COLLISION_WEIGHT, "weight of the collision cost", stage="optimize",
        flag="--collision-weight", low=0, high=defaults.MAX_WEIGHT,
    )
    similarity: str = _setting(
        defaults.SIMILARITY, "how the similarity cost weights the task dimensions over time: "
        "variance (eq. 21: stiff where the demonstrations agree), uniform (constant), inverted "
        "(stiff where they varied: a negative control), precision (minimal intervention: the GMR "
        "precision with its cross-covariances), inverse_variance (its diagonal, no sigma_max "
        "ramp) or oracle (phase-informed eq. 21: its largest weight on the task's critical "
        "phase); each alternative has eq. 21's total weight (importance, the task's measured "
        "tolerance, is for imitate eval and compare)", stage="optimize",
        flag="--similarity", choices=defaults.RUN_SIMILARITIES,
    )
    sigma_max_scale: float = _setting(
        defaults.SIGMA_MAX_SCALE, "eq. 21's sigma_max as a multiple of each dimension's "
        "largest GMR variance: 1 (the paper's) leaves the plan free at the peak-variance step, "
        "above 1 every step keeps a weight", stage="optimize", flag="--sigma-max-scale",
        low=0.1, high=100,
    )
    sweep: tuple[float, ...] = _setting(
        (0.0, 0.03, 0.1, 0.3, 1.0), "collision weights of the Fig. 9 sweep, as fractions of "
        "collision_weight", stage="optimize", low=0, high=1,
    )
    push: bool = _setting(
        defaults.NULLSPACE_PUSH, "where the attractors alone leave less than the collision "
        "margin, optimize once more with a null-space push per attractor (the body's "
        "redundancy, not in the paper); --no-push keeps the attractors' plan (the paper's)",
        stage="optimize", flag="--push",
    )
    max_iter: int = _setting(
        defaults.MAX_ITER, "optimizer iteration limit", stage="optimize", flag="--max-iter",
        low=1, high=10_000,
    )
    options: dict = _setting(
        None, "the task's own settings by name (the defaults of those not given), each a flag "
        "of its own", stage="observe",
    )
    obstacle: assembly.Obstacle | None = _setting(
        None, f"{_OBSTACLE_FORMS}; it stands on the table (footprint on the top, bottom at most "
        f"{defaults.OBSTACLE_MAX_LIFT:g} m above it), clear of the robot and the objects it "
        f"holds at the start.",
        stage="optimize", flag="--obstacle", parse=parse_obstacle, metavar="SHAPE:POS:SIZE",
    )
    video_width: int = _setting(
        640, "video width [px]", stage="figures", flag="--video-width", low=64, high=1920,
        multiple=VIDEO_BLOCK,
    )
    video_height: int = _setting(
        480, "video height [px]", stage="figures", flag="--video-height", low=48, high=1080,
        multiple=VIDEO_BLOCK,
    )
    video_fps: float = _setting(
        25.0, "frame rate of video.mp4 and of the replay's recorded states [Hz]",
        stage="replay", low=1, high=60,
    )
    teacher_speedup: float = _setting(
        4.0, "the teacher's part of the video plays this many times faster (its pauses between "
        "demonstrations faster still)", stage="figures", low=1, high=10,
    )

    def __post_init__(self):
        from imitate.envs import assembly

        if isinstance(self.obstacle, dict):  # from config.json
            values = {k: tuple(v) if isinstance(v, list) else v for k, v in self.obstacle.items()}
            object.__setattr__(self, "obstacle", assembly.Obstacle(**values))
        object.__setattr__(self, "sweep", tuple(float(s) for s in self.sweep))
        for name, setting, _ in settings():
            if name != "options":
                setting.check(name, getattr(self, name))
        object.__setattr__(self, "options", tasks.settings(self.task, self.options))
        if self.task_space not in TASK_SPACES:
            from imitate.demos.space_selection import named
            from imitate.envs.task import get_task

            named(str(self.task_space), get_task(self.task).space.places)
        assembly.check_clearance(self.scene())  # validates the grasps and the obstacle

    @classmethod
    def quick(cls, **overrides) -> RunConfig:
        """Small images, 3 demonstrations, short optimization: the whole run in well under
        a minute (for tests)."""
        values: dict[str, Any] = dict(
            n_demos=3, width=320, height=240, fps=20.0, k_max=10, max_iter=30,
            video_width=320, video_height=240, video_fps=10.0,
        )
        task = overrides.get("task", tasks.DEFAULT)
        quick = {n: o.quick for n, o in tasks.options(task).items() if o.quick is not None}
        values["options"] = {**quick, **(overrides.pop("options", None) or {})}
        return cls(**{**values, **overrides})

    def scene(self, teacher: bool = False, task: Task | None = None) -> assembly.SceneConfig:
        """The robot's scene (objects in its hands, the obstacle, the task's own values) of the
        run's task, or of ``task`` (the run's in the space its model was learned in)."""
        from imitate.envs.task import get_task

        return (task or get_task(self.task)).scene(
            self.options, (self.obstacle,) if self.obstacle else (), teacher=teacher
        )

    def plan_config(self) -> PlanConfig:
        """The planner's settings of the run (the optimize stage's, at its collision weight)."""
        from imitate.motion import PlanConfig

        return PlanConfig(
            collision_weight=self.collision_weight, max_iter=self.max_iter,
            similarity=self.similarity, sigma_max_scale=self.sigma_max_scale,
            nullspace_push=self.push,
        )

    def teacher(self) -> TeacherConfig:
        """The teacher's demonstrations."""
        from imitate.envs.teacher_motion import TeacherConfig

        return TeacherConfig(
            n_demos=self.n_demos, task=self.task, seed=self.seed, variation=self.teacher_variation
        )

    def to_json(self) -> dict[str, Any]:
        """The settings as JSON-ready values (the obstacle as a dict)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, values: dict[str, Any]) -> RunConfig:
        """Settings read back from ``config.json``; unknown names are refused. A file written
        before the task was a setting (neither ``task`` nor ``options``) holds the default
        task's own settings among the others: they are read as its ``options``."""
        if "task" not in values and "options" not in values:
            own = tasks.options(tasks.DEFAULT)
            values = {
                **{name: v for name, v in values.items() if name not in own},
                "options": {name: v for name, v in values.items() if name in own},
            }
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            shown = [name if len(name) <= 40 else f"{name[:40]}..." for name in unknown[:5]]
            more = f" and {len(unknown) - 5} more" if len(unknown) > 5 else ""
            raise ImitateError(
                f"config.json has unknown settings {shown}{more}; accepted: {sorted(names)}"
            )
        return cls(**values)


def settings(stages: Iterable[str | None] | None = None) -> list[tuple[str, Setting, Any]]:
    """``(field name, setting, default)`` of :class:`RunConfig`'s settings in field order; those
    of ``stages`` only if given (``None`` in it: the settings of the whole run)."""
    chosen = None if stages is None else set(stages)
    return [
        (f.name, f.metadata["setting"], f.default)
        for f in dataclasses.fields(RunConfig)
        if chosen is None or f.metadata["setting"].stage in chosen
    ]


def load_config(run_dir: Path) -> RunConfig:
    """The ``config.json`` of ``run_dir``.

    Raises:
        ImitateError: the file is missing or unreadable, not an object of settings, or holds a
            setting of the wrong JSON type or out of range; the message names the file.
    """
    path = Path(run_dir) / "config.json"
    values = load_json(path, hint=table.rerun(path))
    if not isinstance(values, dict):
        raise ImitateError(
            f"{path} holds a JSON {_json_kind_of(values)}, not an object of settings; re-run "
            f"`imitate observe {shell_word(run_dir)}` to write it"
        )
    defaults = {name: default for name, _, default in settings()}
    for name, value in values.items():
        if name == "options":
            fits, kind = _options_fit(value), "null or an object of the task's settings: numbers"
        elif name in defaults:
            fits, kind = _json_fits(value, defaults[name]), _json_kind(defaults[name])
        else:
            continue  # refused by from_json, by name
        if not fits:
            raise ImitateError(f"{path}: {name}={quoted(value)} not accepted: {kind}")
    try:
        return RunConfig.from_json(values)
    except ImitateError as err:
        raise ImitateError(f"{path}: {err}") from None


def _json_kind_of(value: Any) -> str:
    """``value``'s JSON kind (``"list"``, ``"string"``...), not its content (it may be secret)."""
    kinds = {list: "list", str: "string", bool: "boolean", type(None): "null"}
    return kinds.get(type(value), "number")


def _json_fits(value: Any, default: Any) -> bool:
    """Whether the JSON ``value`` has the type of a setting whose default is ``default``."""
    if isinstance(default, bool) or isinstance(value, bool):
        return isinstance(default, bool) and isinstance(value, bool)
    if isinstance(default, tuple):
        return isinstance(value, list) and all(_json_fits(v, 0.0) for v in value)
    if default is None:  # the obstacle
        return value is None or (
            isinstance(value, dict) and set(value) == {"shape", "pos", "size"}
            and isinstance(value["shape"], str)
            and all(_json_fits(value[k], ()) for k in ("pos", "size"))
        )
    if isinstance(default, float):
        return isinstance(value, int | float)
    return isinstance(value, type(default))


def _options_fit(value: Any) -> bool:
    """Whether the JSON ``value`` has the type of the task's settings (numbers by name)."""
    return value is None or (isinstance(value, dict) and all(
        isinstance(v, int | float) and not isinstance(v, bool) for v in value.values()))


def _json_kind(default: Any) -> str:
    """What :func:`_json_fits` accepts for a setting whose default is ``default``."""
    if default is None:
        return 'null or {"shape": "box" or "cylinder", "pos": [x, y, z], "size": [...]}'
    kinds = {bool: "true or false", int: "a whole number", float: "a number",
             str: "a string", tuple: "a list of numbers"}
    return kinds[type(default)]


def _documentation() -> str:
    lines = []
    for name, s, default in settings():
        where = ", ".join(part for part in (s.stage and f"{s.stage} stage", s.flag) if part)
        lines.append(f"        {name} ({where or 'config.json only'}): {s.describe(default)}")
    return "\n\n    Attributes:\n" + "\n".join(lines) + "\n    "


assert RunConfig.__doc__ is not None  # a dataclass always has one (its signature at least)
RunConfig.__doc__ = RunConfig.__doc__.rstrip() + _documentation()
