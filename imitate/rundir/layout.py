"""The files of a run directory, by path relative to it.

The stages' artifacts (which stage writes which: :mod:`imitate.stages.table`; what each holds:
:mod:`imitate.stages.files`), the settings, the report and its page, the manifest and a
teacher's code record. :func:`imitate.rundir.artifacts.leftovers` deletes the temporary files of
these names only.
"""

from __future__ import annotations

__all__ = [
    "CODE", "CONFIG", "DEMOS", "EXPORT", "FIGURES", "MANIFEST", "MODEL", "OBSERVATIONS", "OWN",
    "PAGE", "PLAN", "REPLAY", "REPORT", "VIDEO", "figure",
]

OBSERVATIONS = "observations.npz"  # the tracks, the cameras and the ground truth
DEMOS = "demos.npz"  # the demonstrations cut from the tracks
MODEL = "model.npz"  # the learned model, its gaze frame and what the figures show of learning
PLAN = "plan.npz"  # the optimized movement and the sweep over collision weights
REPLAY = "replay.npz"  # the plan replayed in physics, and the sweep's weight-0 plan
VIDEO = "video.mp4"
FIGURES = (
    "observation", "fig4_gmm_dtw", "fig5_bic", "gmr", "fig8_snapshots", "fig9_collision_sweep",
    "costs",
)
REPORT = "report.json"  # every stage merges its sections into it
PAGE = "report.html"  # the report and the settings as a page (imitate.rundir.page), with the report
CONFIG = "config.json"  # the run's settings, written by every stage
MANIFEST = "manifest.json"  # what each artifact was made from (imitate.stages.provenance)
CODE = "code.json"  # a teacher's run: the code its stages ran with (imitate.evaluation.teachers)
EXPORT = "export"  # the exports' folder


def figure(name: str) -> str:
    """The path of the figure called ``name`` (one of :data:`FIGURES`)."""
    return f"figures/{name}.png"


OWN = (
    OBSERVATIONS, DEMOS, MODEL, PLAN, REPLAY, VIDEO, *(figure(name) for name in FIGURES), CONFIG,
    REPORT, PAGE, MANIFEST, CODE,
)  # every file imitate writes in a run directory (the exports aside)
