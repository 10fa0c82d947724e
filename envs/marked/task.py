"""The marked pour as a :class:`~imitate.envs.task.Task` (``TASK``): the pour's measures and
words, its own space (the glass relative to the marker is part of it) and outcome."""

from __future__ import annotations

import dataclasses

import numpy as np

from imitate.envs.marked.env import MarkedPouringEnv
from imitate.envs.marked.outcome import OUTCOMES, outcome
from imitate.envs.pour.task import TASK as POUR
from imitate.envs.pour.task import pour_phase
from imitate.envs.task import Task
from imitate.models.shapes import MARKER
from imitate.taskspace import Angles, Relative, TaskSpace

__all__ = ["SPACE", "TASK"]

# The bottle relative to the glass (eq. 1's), the glass relative to the marker, the angles.
SPACE = TaskSpace((Relative("tool", "target"), Relative("target", MARKER), Angles("tool"),
                   Angles("target")))
_TILT = int(SPACE.angles[0])  # the bottle's angle column


def marked_pour_phase(mean: np.ndarray) -> np.ndarray:
    """The pour's critical phase (:func:`~imitate.envs.pour.task.pour_phase`) of a learned mean
    ``(T, 10)`` in :data:`SPACE`."""
    return pour_phase(mean, _TILT)


TASK = Task(
    env=MarkedPouringEnv,
    phase="pour",
    outcomes=OUTCOMES,
    outcome=outcome,
    critical=marked_pour_phase,
    watcher=POUR.watcher,
    score=POUR.score,
    words=dataclasses.replace(POUR.words, instruction="pour from the bottle into the glass held "
                                                       "over the marker"),
    exported=POUR.exported,
    space=SPACE,
)
