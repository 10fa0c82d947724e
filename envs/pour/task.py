"""The pouring task as a :class:`~imitate.envs.task.Task` (``TASK``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from imitate.envs.pour.env import PouringEnv
from imitate.envs.pour.geometry import PourGeometry
from imitate.envs.pour.outcome import OUTCOMES, SUCCESS_FRACTION, outcome
from imitate.envs.task import Score, Task
from imitate.rundir.page import Words, shown
from imitate.taskspace import Angles, TaskSpace

__all__ = ["TASK", "pour_phase"]


def pour_phase(mean: np.ndarray, space: TaskSpace) -> np.ndarray:
    """Steps ``(T,) bool`` where the bottle is tilted beyond 80 % of its largest tilt from the
    start, given the GMR mean ``(T, m)`` in ``space`` (its bottle's angle: the first column of
    ``Angles("tool")``): the low-variance pouring phase."""
    column = space.columns(Angles("tool")).start
    tilt = np.abs(mean[:, column] - mean[0, column])
    return tilt >= 0.8 * tilt.max()


def headline(replay: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The run page's headline row of the pour, from the report's replay section."""
    return [(
        "pour fraction",
        f"{shown(replay['pour_fraction'], '.2f')} (mean "
        f"{shown(replay['pour_fraction_mean'], '.2f')}, min "
        f"{shown(replay['pour_fraction_min'], '.2f')} over the replays), "
        f"{shown(replay['spilled'], 'g')} spilled",
    )]


def exported(record: Mapping[str, Any], info: Mapping[str, Any]) -> dict[str, Any]:
    """An exported evaluated episode's pouring metadata: the evaluation's smallest pour over
    the variation's replays (``pour_min``), this episode's pour fraction and whether it poured
    (the env's ``is_success``)."""
    return {
        "pour_min": record["pour_min"], "pour_fraction": float(info["pour_fraction"]),
        "poured": bool(info["is_success"]),
    }


TASK = Task(
    env=PouringEnv,
    phase="pour",
    outcomes=OUTCOMES,
    outcome=outcome,
    critical_steps=pour_phase,
    watcher=PourGeometry,
    score=Score("pour_fraction", SUCCESS_FRACTION, "pour"),
    words=Words(verbs=("pours", "does not pour"), noun="the pour",
                instruction="pour from the bottle into the glass", headline=headline),
    exported=exported,
)
