"""What counts as a pour, and the outcome of a reproduction: one definition for the env's
``is_success``, the ``replay`` stage's ``success`` and the evaluation's outcomes.

Outcomes, the first that applies: ``diverged`` (a replay's physics blew up), ``plan_collision``
(the plan itself comes closer than 0 to something), ``physics_contact`` (the plan keeps clear,
a replay does not), ``spill`` or ``low_pour`` (the smallest pour fraction over the replays is
below :data:`SUCCESS_FRACTION`: ``spill`` when the particles spilled outside both containers are
at least half of those missing from the glass, ``low_pour`` when most stayed in the bottle),
``success``. Success asks for the minimum over the replays, not the mean: the pour is chaotic
(a tiny change of the initial state moves one replay's fraction by a few particles), and a
reproduction that pours in two replays of three is not one that pours.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from imitate.envs.task import shared_outcome

__all__ = ["OUTCOMES", "SUCCESS_FRACTION", "outcome", "poured"]

SUCCESS_FRACTION = 0.9  # of the particles in the glass
OUTCOMES = ("success", "plan_collision", "physics_contact", "spill", "low_pour", "diverged")


def poured(in_glass: float) -> bool:
    """Whether a fraction ``in_glass`` of the particles is a pour (the env's ``is_success``)."""
    return in_glass >= SUCCESS_FRACTION


def outcome(plan_min_distance: float, replays: Sequence[Mapping], options: Mapping) -> str:
    """The outcome (one of :data:`OUTCOMES`) of a plan's clearance [m] and its replays, each
    ``{"pour_fraction", "spilled", "min_distance_m", "diverged"}`` (``options["particles"]``
    of liquid)."""
    particles = options["particles"]
    shared = shared_outcome(plan_min_distance, replays)
    if shared is not None:
        return shared
    worst = min(replays, key=lambda r: r["pour_fraction"])
    if poured(worst["pour_fraction"]):
        return "success"
    missing = 1.0 - worst["pour_fraction"]
    return "spill" if worst["spilled"] / particles >= missing / 2 else "low_pour"
