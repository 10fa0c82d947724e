"""``TrialRecord``: one line of an evaluation's ``results.jsonl``, a variation reproduced and
replayed (:meth:`~imitate.evaluation.trial.Trial.run`), and the names of the keys its task adds.

Beside the fields typed here a record holds the task's numbers, named after its score
(``Task.score``'s name) and its critical phase (``Task.phase``):

- ``<score>_mean``, ``<score>_min``: the mean and the smallest of the score's measure over the
  replays (:func:`score_keys`);
- ``plan["<phase>_phase_err_m"]``, ``plan["<phase>_phase_err_deg"]``: the plan's largest task
  error in the critical phase (:func:`~imitate.motion.metrics.critical_error`,
  :func:`error_keys`);
- ``change``: :func:`~imitate.motion.metrics.task_change`'s ``<phase>_m``, ``<phase>_deg`` and
  ``low_variance_m`` (:func:`change_keys`);
- in each replay, the task's measures (``Task.measures``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, TypedDict, cast

if TYPE_CHECKING:
    from imitate.envs.task import Task

__all__ = [
    "PlanRecord", "ReplayRecord", "TrialRecord", "change_keys", "error_keys", "is_number",
    "score_keys", "task_value",
]


class PlanRecord(TypedDict):
    """The variation's plan (and the task's two ``<phase>_phase_err_*`` keys).

    Attributes:
        min_distance_m: Its smallest signed distance between pairs that must not touch [m].
        closest: The two geoms of that distance.
        iterations: The optimizer's iterations.
        converged: Whether it converged.
        nullspace_push: Whether the null-space push changed it.
        seconds: Time to plan it [s].
    """

    min_distance_m: float
    closest: list[str]
    iterations: int
    converged: bool
    nullspace_push: bool
    seconds: float


class ReplayRecord(TypedDict):
    """One physics replay (and the task's measures at its end).

    Attributes:
        seed: Its seed of the initial-state noise.
        min_distance_m: Smallest signed distance over its steps [m].
        diverged: Whether its physics diverged (it stopped there).
        geometry: What the task's watcher saw (``Task.watcher``'s summary).
    """

    seed: int
    min_distance_m: float
    diverged: bool
    geometry: dict[str, Any]


class _Filed(TypedDict, total=False):
    """What the worker that ran a variation files its record under."""

    digest: str
    teacher: int


class TrialRecord(_Filed):
    """A variation's record (and the task's keys of the module docstring, read by
    :func:`task_value`), as the worker that ran it files it.

    Attributes:
        digest: The evaluation's digest it is filed under (set by the worker).
        teacher: The seed of the teacher whose model reproduced it (set by the worker).
        id: The variation's index.
        settings: The variation's settings (:meth:`Variation.to_json`).
        outcome: One of the task's outcomes (``Task.outcome``).
        plan: Its plan.
        change: How far the plan moved the task from the unconstrained reproduction.
        mahalanobis: ``{"rms"}``: its deviation from the demonstrations in their metric.
        replays: Its physics replays.
        physics_min_distance_m: Smallest signed distance over the replays [m].
        clearance_gap_m: The plan's minus that [m].
        seconds: Time for the whole variation [s].
    """

    id: int
    settings: dict[str, Any]
    outcome: str
    plan: PlanRecord
    change: dict[str, float]
    mahalanobis: dict[str, float]
    replays: list[ReplayRecord]
    physics_min_distance_m: float
    clearance_gap_m: float
    seconds: float


def task_value(record: TrialRecord | PlanRecord, key: str) -> float:
    """A record's value of one of its task's keys (:func:`score_keys`, :func:`error_keys`),
    which the record types cannot name."""
    return cast(Mapping[str, float], record)[key]


def score_keys(task: Task) -> tuple[str, str]:
    """The record's keys of the mean and the smallest score over the replays."""
    return f"{task.score.name}_mean", f"{task.score.name}_min"


def error_keys(task: Task) -> tuple[str, str]:
    """The plan record's keys of its largest position [m] and angle [deg] error in the
    critical phase."""
    return task.error_keys


def change_keys(task: Task) -> tuple[str, str]:
    """The change record's keys of the largest position [m] and angle [deg] change in the
    critical phase (:func:`~imitate.motion.metrics.task_change`'s)."""
    return f"{task.phase}_m", f"{task.phase}_deg"


def is_number(value: object) -> bool:
    """Whether a value read from a record is a number (``true`` and ``false`` are not)."""
    return isinstance(value, int | float) and not isinstance(value, bool)
