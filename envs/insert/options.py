"""The insertion task's own run settings (light: the command line's help reads them)."""

from imitate.envs.tasks import Option
from imitate.models.shapes import GLASS, GRASP, GRASP_RANGE, STICK

OPTIONS = {
    "stick_grasp": Option(
        GRASP[STICK], "where the robot holds the stick, height above its lower end [m]",
        *GRASP_RANGE[STICK],
    ),
    "glass_grasp": Option(
        GRASP[GLASS], "where the robot holds the glass, height above its bottom [m]",
        *GRASP_RANGE[GLASS],
    ),
}
