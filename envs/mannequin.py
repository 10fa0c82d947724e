"""The teacher's mannequin: its arms holding the task's objects where the script puts them.

Each arm is three mocap bodies. Given where a hand should be, :func:`pose_arm` places the hand
there and draws upper arm and forearm by two-link inverse kinematics, elbow down and out, so a
video reads as a person holding the objects; :func:`show` puts the objects at given poses and
draws the arms holding them.
"""

from __future__ import annotations

import mujoco
import numpy as np

from imitate.envs.assembly import grips, objects_in
from imitate.errors import ImitateError
from imitate.models import scene, teacher

__all__ = ["hand_pose_for_object", "holding_side", "pose_arm", "shoulder_position", "show"]

_YAW = np.pi  # the mannequin faces the robot (-x)


def shoulder_position(side: str) -> np.ndarray:
    """World position ``(3,)`` [m] of the teacher's ``side`` (``"left"``/``"right"``) shoulder."""
    if side not in teacher.SIDES:
        raise ImitateError(f"side {side!r} not accepted: one of {teacher.SIDES}")
    x, y, z = teacher.SHOULDER[side]
    c, s = np.cos(_YAW), np.sin(_YAW)
    return np.array(scene.TEACHER_POS) + np.array([c * x - s * y, s * x + c * y, z])


def hand_pose_for_object(
    model: mujoco.MjModel, obj: str, obj_pos: np.ndarray, obj_quat: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """World pose of the teacher's hand that holds ``obj`` at ``(obj_pos, obj_quat)``.

    Inverts the weld's grasp pose (set by ``imitate.envs.assembly.set_grasp``).

    Returns:
        ``(pos (3,) [m], quat (4,) wxyz)`` of the hand body.
    """
    hand, _ = grips("teacher", objects_in(model))[obj]
    eq = model.equality(scene.weld_name(obj, hand))
    inv_pos, inv_quat = np.zeros(3), np.zeros(4)
    mujoco.mju_negPose(inv_pos, inv_quat, eq.data[3:6], eq.data[6:10])
    pos, quat = np.zeros(3), np.zeros(4)
    mujoco.mju_mulPose(
        pos, quat, np.asarray(obj_pos, float), np.asarray(obj_quat, float), inv_pos, inv_quat
    )
    return pos, quat


def pose_arm(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    side: str,
    hand_pos: np.ndarray,
    hand_quat: np.ndarray,
) -> None:
    """Put the teacher's ``side`` hand at ``(hand_pos [m], hand_quat wxyz)`` and draw its arm.

    A target beyond the arm's reach keeps the hand where asked and stretches the arm towards it.
    """
    shoulder = shoulder_position(side)
    wrist = np.asarray(hand_pos, dtype=float)
    l1, l2 = teacher.UPPER_ARM_LENGTH, teacher.FOREARM_LENGTH
    reach = wrist - shoulder
    dist = np.clip(np.linalg.norm(reach), abs(l1 - l2) + 1e-3, l1 + l2 - 1e-4)
    along = reach / max(np.linalg.norm(reach), 1e-9)
    # Elbow bends down and away from the body: the hint is the world's down plus outward.
    outward = 1.0 if side == "right" else -1.0  # teacher faces -x: its right is +y
    hint = np.array([0.0, 0.4 * outward, -1.0])
    bend = hint - hint.dot(along) * along
    bend /= np.linalg.norm(bend)
    cos_a = (l1**2 + dist**2 - l2**2) / (2 * l1 * dist)
    elbow = shoulder + l1 * (cos_a * along + np.sqrt(max(0.0, 1 - cos_a**2)) * bend)
    wrist_reached = elbow + l2 * _unit(wrist - elbow)
    _set_mocap(model, data, teacher.UPPER_ARM[side], shoulder, _segment_quat(shoulder, elbow))
    _set_mocap(model, data, teacher.FOREARM[side], elbow, _segment_quat(elbow, wrist_reached))
    _set_mocap(model, data, teacher.HAND[side], wrist, np.asarray(hand_quat, dtype=float))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(np.linalg.norm(v), 1e-9)


def _segment_quat(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Orientation whose local -z points from ``start`` to ``end``."""
    z = -_unit(end - start)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = _unit(_cross(helper, z))
    y = _cross(z, x)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.column_stack([x, y, z]).ravel())
    return quat


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of two 3-vectors: its arithmetic without its generality, which took two
    thirds of the teacher's posing time per frame."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def _set_mocap(model, data, body: str, pos, quat) -> None:
    mocap_id = model.body_mocapid[model.body(body).id]
    data.mocap_pos[mocap_id] = pos
    data.mocap_quat[mocap_id] = quat


# --- Scripted demonstrations -------------------------------------------------------------------

def show(model: mujoco.MjModel, data: mujoco.MjData, poses: dict[str, tuple]) -> None:
    """Put the objects at ``poses`` and draw the teacher's arms holding them; no physics.

    Args:
        model: a scene built with the teacher.
        data: its data; object free joints and the teacher's mocap bodies are written, then
            kinematics are updated for rendering.
        poses: ``{object: (pos (3,) [m], quat (4,) wxyz)}`` of the object frames; a place
            (a mocap body of the teacher's scene) is moved there, no arm drawn.
    """
    for obj, (pos, quat) in poses.items():
        if model.body(obj).mocapid[0] >= 0:
            _set_mocap(model, data, obj, pos, quat)
            continue
        joint = model.joint(obj)
        data.qpos[joint.qposadr[0] : joint.qposadr[0] + 7] = (*pos, *quat)
        hand_pos, hand_quat = hand_pose_for_object(model, obj, pos, quat)
        pose_arm(model, data, holding_side(model, obj), hand_pos, hand_quat)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)


def holding_side(model: mujoco.MjModel, obj: str) -> str:
    """The teacher's hand (``"left"``/``"right"``) that holds ``obj``."""
    held = grips("teacher", objects_in(model))
    if obj not in held:
        raise ImitateError(f"object {obj!r} not accepted: one of {tuple(held)}")
    hand = held[obj][0]
    return next(side for side in teacher.SIDES if teacher.HAND[side] == hand)
