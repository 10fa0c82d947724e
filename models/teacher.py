"""Element names and dimensions of ``teacher.xml``, the demonstrating mannequin."""

from __future__ import annotations

BODY = "teacher"
SIDES = ("left", "right")
# Mocap bodies per arm, shoulder to hand; the arm segments are posed by envs/teacher_motion.py.
UPPER_ARM = {side: f"teacher_{side}_upper_arm" for side in SIDES}
FOREARM = {side: f"teacher_{side}_forearm" for side in SIDES}
HAND = {side: f"teacher_{side}_hand" for side in SIDES}
GRIP = {side: f"teacher_{side}_grip" for side in SIDES}

# In the teacher's own frame (facing +x, feet at the origin) [m].
SHOULDER = {"left": (0.0, 0.2, 1.42), "right": (0.0, -0.2, 1.42)}
UPPER_ARM_LENGTH = 0.29
FOREARM_LENGTH = 0.26
HEIGHT = 1.75
