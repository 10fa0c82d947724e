"""The insertion task's light part: its Gymnasium id and its own run settings (read by
``import imitate`` and by the command line's help, without MuJoCo)."""

from imitate.envs.tasks import Option
from imitate.models.shapes import GLASS, GRASP, GRASP_RANGE, STICK

ENV_ID, ENV_CLASS = "imitate/Inserting-v0", "InsertingEnv"  # the class in the env module
OPTIONS = {
    "stick_grasp": Option(
        GRASP[STICK], "where the robot holds the stick, height above its lower end [m]",
        *GRASP_RANGE[STICK],
    ),
    # Low on the glass: the left hand's collision capsule reaches into the glass, to 25 mm from its
    # axis; held at pouring's 50 mm it spans 15 to 85 mm above the glass's bottom, where the stick
    # goes, held at 30 mm it ends 65 mm above it.
    "glass_grasp": Option(
        GRASP_RANGE[GLASS][0], "where the robot holds the glass, height above its bottom [m]",
        *GRASP_RANGE[GLASS],
    ),
}
