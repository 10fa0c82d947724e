"""The stages of a run, in order: what each does, its function, what it reads and writes, what
it reports.

The command line, the run files' re-run hints (:func:`rerun`) and
:func:`imitate.stages.runner.run_stage` all read :data:`STAGES`. This module imports nothing
heavy (the command line parses its arguments before MuJoCo loads): a stage's function is named
as ``"module:function"`` and imported when the stage runs.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from imitate.errors import ImitateError, shell_word
from imitate.rundir import layout

__all__ = ["NAMES", "RUN_HELP", "STAGES", "Stage", "find", "producer", "rerun"]


@dataclass(frozen=True)
class Stage:
    """One stage of a run.

    Attributes:
        name: Its sub-command and its key in the report's ``timings``.
        help: One line for ``imitate --help``.
        function: ``"module:function"`` of ``(run_dir: Path, config: RunConfig) -> dict`` that
            runs it and returns its report sections by name.
        reads: Artifacts of earlier stages it reads (its inputs in ``manifest.json``).
        writes: Artifacts it writes, paths relative to the run directory (``config.json``: the
            stage that starts a run).
        sections: The report sections it owns, in report order.
    """

    name: str
    help: str
    function: str
    reads: tuple[str, ...]
    writes: tuple[str, ...]
    sections: tuple[str, ...]

    @property
    def files(self) -> str:
        """What it writes, in words: ``"figures/*.png, video.mp4"`` (``config.json`` aside)."""
        return ", ".join(dict.fromkeys(
            "figures/*.png" if name.startswith("figures/") else name
            for name in self.writes if name != layout.CONFIG
        ))

    def body(self) -> Callable[..., dict]:
        """The stage's function, imported now."""
        module, name = self.function.split(":")
        return getattr(importlib.import_module(module), name)

STAGES = (
    Stage(
        "observe",
        "the teacher demonstrates; track the objects in the robot's eyes; cut the demos",
        "imitate.stages.observe:run",
        (),
        (layout.CONFIG, layout.OBSERVATIONS, layout.DEMOS),
        ("demos", "perception"),
    ),
    Stage(
        "learn",
        "task space, DTW, GMM (components by BIC), GMR mean and variance",
        "imitate.stages.learn:run",
        (layout.OBSERVATIONS, layout.DEMOS),
        (layout.MODEL,),
        ("learning",),
    ),
    Stage(
        "optimize",
        "whole-body attractor optimization of the reproduction, Fig. 9 sweep",
        "imitate.stages.optimize:run",
        (layout.MODEL,),
        (layout.PLAN,),
        ("optimization",),
    ),
    Stage(
        "replay",
        "the optimized movement in full physics: the task's measures, clearance, outcome",
        "imitate.stages.replay:run",
        (layout.PLAN, layout.MODEL),
        (layout.REPLAY,),
        ("replay",),
    ),
    Stage(
        "figures",
        "figures/*.png and video.mp4 from the run's artifacts",
        "imitate.stages.figures:run",
        (layout.OBSERVATIONS, layout.DEMOS, layout.MODEL, layout.PLAN, layout.REPLAY),
        (layout.VIDEO, *(layout.figure(name) for name in layout.FIGURES)),
        ("video",),
    ),
)
NAMES = tuple(s.name for s in STAGES)
RUN_HELP = f"all stages: {', '.join(NAMES)}"


def find(name: str) -> Stage:
    """The stage called ``name``.

    Raises:
        ImitateError: no such stage; the message lists them.
    """
    for s in STAGES:
        if s.name == name:
            return s
    raise ImitateError(f"stage {name!r} unknown; accepted: {NAMES}")


def producer(artifact: str) -> str:
    """The command that writes ``artifact`` (a path relative to the run directory): its stage,
    or ``"run"`` for the report and anything no stage writes."""
    return next((s.name for s in STAGES if artifact in s.writes), "run")


def rerun(path: Path) -> str:
    """What to do about the run file ``path`` when it is missing or unusable: ``"re-run
    `imitate learn RUN` to write it"`` (the command of :func:`producer`)."""
    path = Path(path)
    return f"re-run `imitate {producer(path.name)} {shell_word(path.parent)}` to write it"
