"""The task objects as data: names, shapes, colours and where a hand may hold each (light: no
MuJoCo, no trimesh; :mod:`imitate.models.objects` builds them).

Each object is a container whose frame sits at the centre of its bottom, ``z`` along its long
axis: the bottle and the glass of the pouring task, the stick (a narrow tube, open at the top)
that the insertion task puts into the glass, and the marker, a peg that stands on the table to
mark a place (it is never held).
"""

from __future__ import annotations

from dataclasses import dataclass

BOTTLE, GLASS, STICK, MARKER = "bottle", "glass", "stick", "marker"


@dataclass(frozen=True)
class ContainerShape:
    """A thin-walled vessel, open at the top, as a profile of wall segments.

    Attributes:
        profile: ``(n, 2)`` points ``(radius, height)`` of the wall's mid-surface, bottom to
            rim [m].
        wall: wall thickness [m].
        segments: boxes per ring of the collision wall.
        rgba: the one uniform colour.
    """

    profile: tuple[tuple[float, float], ...]
    wall: float
    segments: int
    rgba: tuple[float, float, float, float]

    @property
    def height(self) -> float:
        """Height of the rim above the bottom [m]."""
        return self.profile[-1][1]


# Saturated hues far from everything else in the scene: green bottle, blue glass.
BOTTLE_SHAPE = ContainerShape(
    profile=((0.034, 0.0), (0.034, 0.15), (0.016, 0.195), (0.016, 0.235)),
    wall=0.004,
    segments=16,
    rgba=(0.10, 0.72, 0.22, 1.0),
)
GLASS_SHAPE = ContainerShape(
    profile=((0.036, 0.0), (0.042, 0.10)),
    wall=0.004,
    segments=18,
    rgba=(0.12, 0.30, 0.92, 1.0),
)
# A narrow magenta tube, three times as long as the glass is deep, held above its middle: its top
# shows beyond the hand holding it while its lower end is in the glass. Its hue is as far from the
# glass's blue as from the teacher's skin and hair (an orange one shared their hues).
STICK_SHAPE = ContainerShape(
    profile=((0.010, 0.0), (0.010, 0.30)),
    wall=0.004,
    segments=10,
    rgba=(0.78, 0.12, 0.74, 1.0),
)
# A lime peg that marks a place on the table: taller than wide, so that its silhouette has an
# axis for the tracker, as the stick's; its hue (about 74 deg) lies between the teacher's hair
# (about 24 deg) and the bottle's green (about 132 deg), far from both.
MARKER_SHAPE = ContainerShape(
    profile=((0.015, 0.0), (0.015, 0.08)),
    wall=0.004,
    segments=10,
    rgba=(0.70, 0.90, 0.05, 1.0),
)
SHAPES = {  # the objects by name
    BOTTLE: BOTTLE_SHAPE, GLASS: GLASS_SHAPE, STICK: STICK_SHAPE, MARKER: MARKER_SHAPE,
}
# Where a hand may hold each object, height above its bottom [m], and where it does by default
# (the held ones).
GRASP_RANGE = {BOTTLE: (0.05, 0.13), GLASS: (0.03, 0.08), STICK: (0.14, 0.22)}
GRASP = {BOTTLE: 0.09, GLASS: 0.05, STICK: 0.18}


