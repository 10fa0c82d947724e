"""The marked pour's teacher: the pour's waypoints (:mod:`imitate.envs.pour.teacher`) moved so
that the glass is held over a marker standing on the teacher's side of the table while the
bottle pours (:data:`SCRIPT`).

The whole demonstration is moved by :data:`SHIFT`: 6 cm towards the robot, so that the marker
under the pour stands on the table, and 25 cm down, so that the glass pours 4 to 16 cm above
the marker's top (within the robot's reach when it does the same over its own marker). Around the
pour the glass keeps within :data:`OVER_SPREAD` of over the marker (the pour's spread is 2 cm):
where the marker is, the teacher is exact. The bottle relative to the glass, the tilts, the
time warps and the tremor are the pour's.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from imitate.envs.assembly import Place
from imitate.envs.pour.teacher import SCRIPT as POUR
from imitate.models.shapes import MARKER

__all__ = ["MARKER_PLACE", "SCRIPT", "SHIFT"]

SHIFT = np.array((-0.06, 0.0, -0.30))  # [m] the glass's bottom, from the pour's
OVER_SPREAD = 0.006  # [m] the glass's spread over demonstrations from the pour's start to its end
_POUR_ROWS = range(3, 7)  # the tilt up, the pour (the script's agree rows), the tilt back


def _moved(row: tuple, index: int) -> tuple:
    """A pour waypoint with the glass moved by :data:`SHIFT` (and held tighter around the
    pour)."""
    u, glass, glass_tilt, mouth, tilt, spreads = row
    if index in _POUR_ROWS:
        spreads = (min(spreads[0], OVER_SPREAD), *spreads[1:])
    moved = tuple(round(float(v), 6) for v in np.add(glass, SHIFT))
    return u, moved, glass_tilt, mouth, tilt, spreads


_POUR_AT = np.mean([POUR.waypoints[i][1] for i in POUR.agree_rows], axis=0) + SHIFT
# Under the middle of the pour: the glass's bottom centre there, on the table.
MARKER_PLACE = Place(MARKER, round(float(_POUR_AT[0]), 6), round(float(_POUR_AT[1]), 6))
SCRIPT = dataclasses.replace(
    POUR,
    waypoints=tuple(_moved(row, i) for i, row in enumerate(POUR.waypoints)),
    places=(MARKER_PLACE,),
    head_tilt=0.30,  # 0.22 rad more than the pour's: the demonstration is 30 cm lower
)
