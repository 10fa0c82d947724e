"""The pouring task's light part: its Gymnasium id and its own run settings (read by
``import imitate`` and by the command line's help, without MuJoCo)."""

from imitate.envs.tasks import Option
from imitate.models.shapes import BOTTLE, GLASS, GRASP, GRASP_RANGE

ENV_ID, ENV_CLASS = "imitate/Pouring-v0", "PouringEnv"  # the class in the env module
MAX_PARTICLES = 120  # what fits in the bottle below its shoulder
OPTIONS = {
    "bottle_grasp": Option(
        GRASP[BOTTLE], "where the robot holds the bottle, height above its bottom [m]",
        *GRASP_RANGE[BOTTLE],
    ),
    "glass_grasp": Option(
        GRASP[GLASS], "where the robot holds the glass, height above its bottom [m]",
        *GRASP_RANGE[GLASS],
    ),
    "particles": Option(
        60, "liquid spheres in the bottle", 1, MAX_PARTICLES, integer=True, stage="replay",
        quick=30, suite=(30, 60),
    ),
}
