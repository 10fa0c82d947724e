"""The insertion task as a :class:`~imitate.envs.task.Task` (``TASK``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from imitate.envs.insert.env import InsertingEnv
from imitate.envs.insert.geometry import InsertGeometry
from imitate.envs.insert.outcome import OUTCOMES, SUCCESS_DEPTH, outcome
from imitate.envs.task import Score, Task
from imitate.models import objects
from imitate.rundir.page import Words, shown
from imitate.taskspace import Relative, TaskSpace

__all__ = ["TASK", "insert_phase"]

_RIM = objects.GLASS_SHAPE.profile[-1][0] - objects.GLASS_SHAPE.wall / 2  # inner radius [m]
_ABOVE = 0.01  # [m]: how far above the rim the insertion phase starts


def insert_phase(mean: np.ndarray, space: TaskSpace) -> np.ndarray:
    """Steps ``(T,) bool`` where the GMR mean ``(T, m)`` in ``space`` (its stick relative to the
    glass, ``Relative("tool", "target")``) holds the stick's lower end over the glass's opening
    (within the rim's inner radius of the glass's axis) and at most 1 cm above the rim: the
    low-variance descent into the glass. Where it never does, the steps where the end is
    nearest to the glass's axis (within 1 cm of the nearest)."""
    dx, dy, dz = mean[:, space.columns(Relative("tool", "target"))].T
    offset = np.hypot(dx, dy)
    phase = (offset < _RIM) & (dz <= objects.GLASS_SHAPE.height + _ABOVE)
    return phase if phase.any() else offset <= offset.min() + 0.01


def headline(replay: Mapping[str, Any]) -> list[tuple[str, str]]:
    """The run page's headline row of the insertion, from the report's replay section."""
    return [(
        "insertion depth",
        f"{shown(replay['insert_depth'], '.1f', 1e3)} mm (mean "
        f"{shown(replay['insert_depth_mean'], '.1f', 1e3)}, min "
        f"{shown(replay['insert_depth_min'], '.1f', 1e3)} over the replays), "
        f"{shown(replay['insert_offset'], '.1f', 1e3)} mm from the glass's axis",
    )]


def exported(record: Mapping[str, Any], info: Mapping[str, Any]) -> dict[str, Any]:
    """An exported evaluated episode's inserting metadata: the evaluation's smallest depth over
    the variation's replays (``insert_min``), this episode's depth and whether it inserted (the
    env's ``is_success``)."""
    return {
        "insert_min": record["insert_min"], "insert_depth": float(info["insert_depth"]),
        "inserted": bool(info["is_success"]),
    }


TASK = Task(
    env=InsertingEnv,
    phase="insert",
    outcomes=OUTCOMES,
    outcome=outcome,
    critical_steps=insert_phase,
    watcher=InsertGeometry,
    score=Score("insert_depth", SUCCESS_DEPTH, "insert", unit="mm", scale=1000.0),
    words=Words(verbs=("inserts", "does not insert"), noun="the insertion",
                instruction="put the stick into the glass", headline=headline),
    exported=exported,
)
