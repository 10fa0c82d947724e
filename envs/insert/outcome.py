"""What counts as an insertion, and the outcome of a reproduction: one definition for the env's
``is_success``, the ``replay`` stage's ``success`` and the evaluation's outcomes.

An insertion: the stick's lower end went at least :data:`SUCCESS_DEPTH` below the glass's rim,
inside the glass (:func:`imitate.envs.insert.geometry.stick_end`), at the deepest point of the
movement. Outcomes, the first that applies: ``diverged`` (a replay's physics blew up),
``plan_collision`` (the plan itself comes closer than 0 to something; the stick in the glass,
clear of its walls, is not a collision), ``physics_contact`` (the plan keeps clear, a replay
does not: the stick meeting the glass's wall is one), ``missed`` (in some replay the end never
was in the glass: it met the rim or passed beside it), ``shallow`` (it was, but in some replay
less than :data:`SUCCESS_DEPTH` deep), ``success``. As for pouring, every replay has to insert:
the smallest depth over the replays decides.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from imitate.envs.task import shared_outcome

__all__ = ["OUTCOMES", "SUCCESS_DEPTH", "inserted", "outcome"]

SUCCESS_DEPTH = 0.03  # [m] below the glass's rim
OUTCOMES = ("success", "plan_collision", "physics_contact", "missed", "shallow", "diverged")


def inserted(depth: float) -> bool:
    """Whether a depth in the glass [m] is an insertion (the env's ``is_success``)."""
    return depth >= SUCCESS_DEPTH


def outcome(plan_min_distance: float, replays: Sequence[Mapping], options: Mapping) -> str:
    """The outcome (one of :data:`OUTCOMES`) of a plan's clearance [m] and its replays, each
    ``{"insert_depth", "insert_offset", "min_distance_m", "diverged"}`` (``options``: the
    task's settings, unused)."""
    shared = shared_outcome(plan_min_distance, replays)
    if shared is not None:
        return shared
    depth = min(r["insert_depth"] for r in replays)
    if inserted(depth):
        return "success"
    return "shallow" if depth > 0 else "missed"
