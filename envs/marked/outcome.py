"""What counts as a marked pour, and the outcome of a reproduction: one definition for the env's
``is_success``, the ``replay`` stage's ``success`` and the evaluation's outcomes.

A marked pour is a pour (:mod:`imitate.envs.pour.outcome`) with the glass over the marker
throughout: at every step at which liquid left the bottle, the marker's axis passed under the
glass's bottom (within :data:`OVER` of the glass's axis). Outcomes, the first that applies: the
pour's (``diverged``, ``plan_collision``, ``physics_contact``, ``spill``, ``low_pour``), then
``off_marker`` (some replay poured, but not over the marker), ``success``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from imitate.envs.pour import outcome as pour
from imitate.models.shapes import GLASS_SHAPE

__all__ = ["OUTCOMES", "OVER", "over", "outcome"]

OVER = GLASS_SHAPE.profile[0][0]  # [m]: the glass's bottom radius
OUTCOMES = (*pour.OUTCOMES[:-1], "off_marker", pour.OUTCOMES[-1])


def over(offset: float) -> bool:
    """Whether the glass's largest horizontal distance [m] from the marker's axis while pouring
    keeps the marker under it."""
    return offset <= OVER


def outcome(plan_min_distance: float, replays: Sequence[Mapping], options: Mapping) -> str:
    """The outcome (one of :data:`OUTCOMES`) of a plan's clearance [m] and its replays, each
    ``{"pour_fraction", "spilled", "marker_offset", "min_distance_m", "diverged"}``
    (``options["particles"]`` of liquid)."""
    poured = pour.outcome(plan_min_distance, replays, options)
    if poured != "success":
        return poured
    return "success" if all(over(r["marker_offset"]) for r in replays) else "off_marker"
