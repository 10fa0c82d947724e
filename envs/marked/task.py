"""The marked pour as a :class:`~imitate.envs.task.Task` (``TASK``): the pour's measures and
words, its own space (the glass relative to the marker is part of it) and outcome."""

from __future__ import annotations

import dataclasses

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

TASK = Task(
    env=MarkedPouringEnv,
    phase="pour",
    outcomes=OUTCOMES,
    outcome=outcome,
    critical_steps=pour_phase,
    watcher=POUR.watcher,
    score=POUR.score,
    words=dataclasses.replace(POUR.words, instruction="pour from the bottle into the glass held "
                                                       "over the marker"),
    exported=POUR.exported,
    space=SPACE,
)
