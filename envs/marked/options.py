"""The marked pour's light part: its Gymnasium id and its own run settings (read by
``import imitate`` and by the command line's help, without MuJoCo)."""

from imitate.envs.pour.options import OPTIONS as POUR_OPTIONS
from imitate.envs.tasks import Option

ENV_ID, ENV_CLASS = "imitate/MarkedPouring-v0", "MarkedPouringEnv"  # the class in the env module
# Where the marker stands in the robot's scene: in reach of the robot's left hand over the table,
# the suite's ranges within that reach (the teacher's marker stands across the table, 0.6 m away).
OPTIONS = {
    **POUR_OPTIONS,
    "marker_x": Option(0.45, "where the marker stands on the table, x [m] (away from the robot)",
                       0.42, 0.58, suite=(0.43, 0.50)),
    "marker_y": Option(0.0, "where the marker stands on the table, y [m] (to the robot's left)",
                       -0.15, 0.2, suite=(-0.06, 0.06)),
}
