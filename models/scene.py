"""Element names and dimensions of ``scene.xml`` and of what ``imitate.envs.assembly`` adds."""

from __future__ import annotations

FLOOR = "floor"
TABLE = "table"
TABLE_TOP = "table_top"
OVERVIEW = "overview"  # camera looking at robot, table and teacher from the side
TEACHER_VIEW = "teacher_view"  # the teacher's hands from above the robot's left shoulder
POUR_VIEW = "pour_view"  # the robot's hands from the teacher's side: the stream of liquid shows
CAMERAS = (OVERVIEW, TEACHER_VIEW, POUR_VIEW, "workspace", "left_eye", "right_eye")

# Table top in the world frame [m]: x from the robot's side to the teacher's, y across.
TABLE_X = (0.40, 1.16)
TABLE_Y = (-0.55, 0.55)
TABLE_HEIGHT = 0.61  # low enough that the robot's glass hand clears it while pouring

TEACHER_POS = (1.55, 0.0, 0.0)  # the mannequin's feet, facing the robot (-x)

OBSTACLE_PREFIX = "obstacle_"


def weld_name(obj: str, hand: str) -> str:
    """Name of the weld constraint that holds ``obj`` in ``hand`` (a body name)."""
    return f"{obj}_in_{hand}"
