"""Element names and constants of ``humanoid.xml``, the ASIMO-like robot."""

from __future__ import annotations

import numpy as np

TORSO_JOINTS = ("torso_yaw", "torso_pitch")
HEAD_JOINTS = ("head_pan", "head_tilt")
ARM_JOINT_SUFFIXES = (
    "shoulder_pitch",
    "shoulder_roll",
    "shoulder_yaw",
    "elbow",
    "wrist_yaw",
    "wrist_pitch",
    "wrist_roll",
)
RIGHT_ARM_JOINTS = tuple(f"right_{s}" for s in ARM_JOINT_SUFFIXES)
LEFT_ARM_JOINTS = tuple(f"left_{s}" for s in ARM_JOINT_SUFFIXES)
# Actuated joints in actuator order; each actuator has its joint's name.
JOINTS = TORSO_JOINTS + HEAD_JOINTS + RIGHT_ARM_JOINTS + LEFT_ARM_JOINTS
ACTUATORS = JOINTS

ROOT_BODY = "pelvis"
BODIES = (
    "pelvis",
    "torso",
    "head",
    "right_upper_arm",
    "right_forearm",
    "right_hand",
    "left_upper_arm",
    "left_forearm",
    "left_hand",
)
RIGHT_HAND, LEFT_HAND = "right_hand", "left_hand"
RIGHT_GRIP, LEFT_GRIP = "right_grip", "left_grip"  # sites: z along the held object's axis
LEFT_EYE, RIGHT_EYE = "left_eye", "right_eye"  # cameras, 10 cm apart
WORKSPACE = "workspace"  # camera under the eyes, looking down at the hands
CAMERAS = (WORKSPACE, LEFT_EYE, RIGHT_EYE)  # the robot's own, in its head

# Rest pose [rad]: elbows bent 90 degrees, forearms forward, the held objects upright in front
# of the chest, head tilted down towards the table. Joints not listed are 0.
REST_POSE = {
    "head_tilt": 0.25,
    "right_shoulder_pitch": -0.35,
    "right_shoulder_roll": -0.12,
    "right_elbow": -1.25,
    "right_wrist_pitch": 0.0,
    "left_shoulder_pitch": -0.35,
    "left_shoulder_roll": 0.12,
    "left_elbow": -1.25,
    "left_wrist_pitch": 0.0,
}


def rest_pose() -> np.ndarray:
    """Joint angles of the rest pose in ``JOINTS`` order, shape ``(18,)`` [rad]."""
    return np.array([REST_POSE.get(name, 0.0) for name in JOINTS])
