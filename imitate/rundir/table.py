"""The stages of a run, in order: what each does, its function, what it writes, what it reports.

The command line, the artifacts' re-run hints and :func:`imitate.stages.runner.run_stage` all
read :data:`STAGES`. This module imports nothing heavy (the command line parses its arguments before
MuJoCo loads, and :mod:`imitate.rundir.artifacts` reads it): a stage's function is named as
``"module:function"`` and imported when the stage runs.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from dataclasses import dataclass

from imitate.errors import ImitateError

__all__ = [
    "CODE", "CONFIG", "FIGURES", "MANIFEST", "NAMES", "PAGE", "REPORT", "RUN_HELP", "STAGES",
    "Stage", "find", "own_names", "producer",
]

REPORT = "report.json"  # every stage merges its sections into it
PAGE = "report.html"  # the report and the settings as a page (imitate.rundir.page), with the report
CONFIG = "config.json"  # the run's settings, written by every stage
MANIFEST = "manifest.json"  # what each artifact was made from (imitate.stages.provenance)
CODE = "code.json"  # a teacher's run: the code its stages ran with (imitate.evaluation.teachers)
FIGURES = (
    "observation", "fig4_gmm_dtw", "fig5_bic", "gmr", "fig8_snapshots", "fig9_collision_sweep",
    "costs",
)


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
            for name in self.writes if name != "config.json"
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
        ("config.json", "observations.npz", "demos.npz"),
        ("demos", "perception"),
    ),
    Stage(
        "learn",
        "task space, DTW, GMM (components by BIC), GMR mean and variance",
        "imitate.stages.learn:run",
        ("observations.npz", "demos.npz"),
        ("model.npz",),
        ("learning",),
    ),
    Stage(
        "optimize",
        "whole-body attractor optimization of the reproduction, Fig. 9 sweep",
        "imitate.stages.optimize:run",
        ("model.npz",),
        ("plan.npz",),
        ("optimization",),
    ),
    Stage(
        "replay",
        "the optimized movement in full physics: pour fraction, spill, clearance",
        "imitate.stages.replay:run",
        ("plan.npz", "model.npz"),
        ("replay.npz",),
        ("replay",),
    ),
    Stage(
        "figures",
        "figures/*.png and video.mp4 from the run's artifacts",
        "imitate.stages.figures:run",
        ("observations.npz", "demos.npz", "model.npz", "plan.npz", "replay.npz"),
        ("video.mp4", *(f"figures/{name}.png" for name in FIGURES)),
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


def own_names() -> tuple[str, ...]:
    """Every file imitate writes in a run directory, paths relative to it: the stages'
    artifacts, the settings, the report and its page, the manifest and a teacher's code
    record."""
    return (*dict.fromkeys(n for s in STAGES for n in s.writes), CONFIG, REPORT, PAGE, MANIFEST,
            CODE)


def producer(artifact: str) -> str:
    """The command that writes ``artifact`` (a path relative to the run directory): its stage,
    or ``"run"`` for the report and anything no stage writes."""
    return next((s.name for s in STAGES if artifact in s.writes), "run")
