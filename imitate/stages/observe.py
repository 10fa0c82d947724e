"""The ``observe`` stage: the teacher demonstrates, the robot's eyes track the objects,
stillness cuts the demonstrations (``observations.npz``, ``demos.npz``)."""

from __future__ import annotations

import logging
from pathlib import Path

import numpy as np

from imitate.demos.segment import StillnessConfig, segment
from imitate.envs.observation import ObservationConfig
from imitate.envs.task import Task
from imitate.perception.accuracy import demo_counts, tracking_errors
from imitate.perception.watch import watch
from imitate.stages.config import RunConfig
from imitate.stages.files import DemosFile, ObservationsFile
from imitate.stages.progress import bar

log = logging.getLogger(__name__)


def run(run_dir: Path, config: RunConfig, task: Task) -> dict:
    """The teacher demonstrates ``task``, the robot's eyes track what it shows (its objects and
    places), stillness cuts the demos."""
    watching = ObservationConfig(
        teacher=config.teacher(),
        fps=config.fps, width=config.width, height=config.height,
    )
    timing: dict[str, float] = {}
    observations = watch(watching, timing=timing, progress=bar)
    demos = segment(observations.tracks, StillnessConfig())
    tracks = observations.tracks
    ObservationsFile(observations).save(run_dir)
    DemosFile(tuple(demos), tracks.objects, tracks.gaze).save(run_dir)
    found = np.array([(d.start, d.end) for d in demos])
    assert observations.truth is not None  # watch() simulates the frames: it keeps the truth
    return {
        "demos": demo_counts(found, observations.truth.boundaries),
        "perception": {
            **tracking_errors(observations),
            "render_pairs_per_s": timing["pairs"] / timing["render"],
            "track_pairs_per_s": timing["pairs"] / timing["track"],
        },
    }
