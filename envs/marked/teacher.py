"""The marked pour's teacher: the pour's waypoints (:mod:`imitate.envs.pour.teacher`) moved so
that the glass is held over a marker while the bottle pours (:data:`SCRIPT`).

The whole demonstration is moved 6 cm towards the robot (:data:`SHIFT`), so that the marker under
the pour stands over the table. The teacher's marker stands on a post (:data:`LIFT`), its top 6
cm under the glass as the pour begins: the teacher pours where the robot watches it best, as the
pour's teacher does, while the robot's own marker stands on the table, the glass as high above
it as the teacher's above its own (within the robot's reach). The place varies from scene to
scene in height too; the task space, relative to the marker, does not. Around the pour the
glass keeps within :data:`OVER_SPREAD` of over the marker (the pour's spread is 2 cm): where the
marker is, the teacher is exact. Between two demonstrations the teacher moves the marker (within
:data:`PLACE_SPREAD`) and pours over it where it stands, so that the demonstrations agree on the
glass relative to the marker around the pour, not on its way there and back. The bottle
relative to the glass, the tilts, the time warps and the tremor are the pour's.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from imitate.envs.assembly import Place
from imitate.envs.marked.outcome import over
from imitate.envs.pour.teacher import SCRIPT as POUR
from imitate.envs.pour.teacher import demonstrated as pours
from imitate.envs.teacher_motion import TeacherMotion
from imitate.models.shapes import GLASS, MARKER

__all__ = ["LIFT", "MARKER_PLACE", "PLACE_SPREAD", "SCRIPT", "SHIFT", "demonstrated"]

SHIFT = np.array((-0.06, 0.0, 0.0))  # [m] the glass's bottom, from the pour's
LIFT = 0.27  # [m] the teacher's marker's bottom above the table top
OVER_SPREAD = 0.006  # [m] the glass's spread over demonstrations from the pour's start to its end
# [m] the marker stands within +-2.5 cm (x: the table's edge) and +-4 cm (y) of MARKER_PLACE
PLACE_SPREAD = (0.025, 0.04)
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
# Under the middle of the pour: below the glass's bottom centre there, on its post.
MARKER_PLACE = Place(MARKER, round(float(_POUR_AT[0]), 6), round(float(_POUR_AT[1]), 6), LIFT)
SCRIPT = dataclasses.replace(
    POUR,
    waypoints=tuple(_moved(row, i) for i, row in enumerate(POUR.waypoints)),
    places=(MARKER_PLACE,),
    place_spread=PLACE_SPREAD,
    placed_rows=tuple(_POUR_ROWS),
    couple=None,  # the glass stays over its marker
)


def demonstrated(motion: TeacherMotion, demo: int) -> bool:
    """Whether demonstration ``demo`` of ``motion`` pours in physics (the pour's check) with the
    glass over the marker where it stood, all through the pour (the script's agree rows)."""
    start, end = motion.boundaries[demo]
    times = np.linspace(start, end, 200)
    _, u = motion.phase(times)
    first, last = (SCRIPT.waypoints[row][0] for row in SCRIPT.agree_rows)
    glass = motion.poses(times[(u >= first) & (u <= last)])[GLASS][0]
    (marker,) = motion.places[demo]
    return over(float(np.hypot(*(glass[:, :2] - (marker.x, marker.y)).T).max())) and pours(
        motion, demo
    )
