"""The inserting teacher: the nominal insertion as waypoints (:data:`SCRIPT`), and
:func:`teacher_insert`, which performs a demonstration in physics to check that the script
inserts.

Where the demonstrations vary (``TeacherConfig.variation``):
- "aligned": as the waypoints' spreads say, centimetres on the approach and millimetres and a
  degree in the descent into the glass, so that the demonstrations agree where the task is.
- "misaligned": outside the descent everything that moves the task space is the nominal; in it
  each demonstration holds the stick higher or lower (world z, along the glass's axis) by its own
  offset, spread evenly over +-``offset`` (25 mm), so the depth varies by centimetres where the
  task is. In physics (:func:`teacher_insert`, seeds 0-2) every one still put the stick into the
  glass, 60 to 94 mm deep: the deepest offset presses it onto the glass's floor.
"""

from __future__ import annotations

import mujoco
import numpy as np

from imitate.envs.assembly import SceneConfig, build_model, hold
from imitate.envs.insert.geometry import stick_end
from imitate.envs.insert.outcome import inserted
from imitate.envs.mannequin import hand_pose_for_object, holding_side
from imitate.envs.teacher_motion import Script, TeacherMotion
from imitate.errors import ImitateError
from imitate.models import humanoid, objects, shapes, teacher

__all__ = ["DEPTH", "SCRIPT", "demonstrated", "teacher_insert"]

DEPTH = 0.085  # [m]: how far below the glass's rim the teacher puts the stick's lower end
# The nominal insertion as waypoints in a demonstration's phase u in [0, 1]: the glass bottom [m],
# the glass tilt towards the stick [deg], the stick's top relative to the glass rim centre [m]
# and the stick tilt towards the glass [deg]; with each waypoint's spread over demonstrations
# (one standard deviation, [m] and [deg]; the stick's top either one value or per axis x, y, z).
# The first and last rows are the rest pose, shared with the previous and next demonstration:
# the stick upright beside the glass, its lower end 3 cm above the glass's bottom.
# - Approach (rows 1-2): the stick is lifted, tilted towards the glass and drawn out in front of
#   the glass, towards the robot (world -x), and up; how far varies most (6 cm, against 2.5 cm
#   sideways and up), one draw per demonstration, centred over the session. Followed exactly,
#   the approach brings the robot's stick into its own chest and shoulders: the reproduction
#   has to leave the demonstrated mean where the demonstrations varied.
# - Above the glass (rows 3-4): upright, the lower end 6 cm over the rim within a centimetre,
#   then 8 mm over it within 2 mm and a degree.
# - Descent (rows 5-6): down the glass's axis to 12 mm short of DEPTH, then on to DEPTH, within
#   2 mm and a degree, while both hands rise (the glass by 6 cm): never still, so the stillness
#   segmentation does not cut a demonstration in two (with the glass rising 2 cm there, 2 of the
#   50 demonstrations of seeds 0-9 were cut at depth), and long enough at depth that smoothing
#   the tracks keeps it.
# - Withdrawal (rows 7-8): up out of the glass as the glass is lowered, then back beside it.
# DEPTH is deep, 11 mm above the glass's floor: the robot's eyes do not see the stick's lower
# part in the glass, so its tracked middle rises by half the hidden length, and the robot learns
# an insertion about half as deep (the default runs of seeds 0-9 inserted 34 to 41 mm deep).
_APPROACH = (0.06, 0.025, 0.025)  # spread of the stick's top: towards the robot, sideways, up
_HEIGHT = shapes.STICK_SHAPE.height
_WAYPOINTS = (
    # u,  glass bottom,        tilt, top - rim,             tilt, spreads (glass, tilt, top, tilt)
    (0.00, (1.21, 0.11, 1.00), 0.0, (0.00, -0.24, _HEIGHT - 0.07), 0.0, (0.020, 0.0, 0.006, 0.0)),
    (0.13, (1.20, 0.08, 1.02), 2.0, (-0.30, -0.12, 0.25), 12.0, (0.020, 1.5, _APPROACH, 5.0)),
    (0.26, (1.19, 0.07, 1.02), 2.0, (-0.48, -0.05, 0.22), 22.0, (0.020, 1.5, _APPROACH, 5.0)),
    (0.40, (1.19, 0.07, 1.02), 0.0, (-0.01, 0.00, _HEIGHT + 0.06), 3.0, (0.020, 1.0, 0.010, 3.0)),
    (0.49, (1.19, 0.07, 1.02), 0.0, (0.00, 0.00, _HEIGHT + 0.008), 0.0, (0.020, 0.5, 0.002, 0.7)),
    (0.60, (1.19, 0.07, 1.04), 0.0, (0.00, 0.00, _HEIGHT + 0.012 - DEPTH), 0.0,
     (0.020, 0.5, 0.002, 0.7)),
    (0.75, (1.19, 0.06, 1.10), 0.0, (0.00, 0.00, _HEIGHT - DEPTH), 0.0, (0.003, 0.5, 0.002, 0.7)),
    (0.85, (1.19, 0.06, 1.05), 1.0, (0.00, 0.00, _HEIGHT + 0.02), 2.0, (0.020, 1.5, 0.010, 4.0)),
    (0.93, (1.20, 0.09, 1.04), 1.0, (0.00, -0.14, _HEIGHT - 0.04), 3.0, (0.020, 1.5, 0.015, 4.0)),
    (1.00, (1.21, 0.11, 1.00), 0.0, (0.00, -0.24, _HEIGHT - 0.07), 0.0, (0.020, 0.0, 0.006, 0.0)),
)

SCRIPT = Script(
    objects=(objects.STICK, objects.GLASS),
    waypoints=_WAYPOINTS,
    swing_rows=(1, 2),  # a demonstration's approach is wide or narrow as a whole: one draw
    agree_rows=(5, 6),  # the descent: the glass keeps its offset from the nominal
    offset_axis=6,  # the stick top's world z (in the waypoints' columns): along the glass's axis
)


def teacher_insert(motion: TeacherMotion, demo: int) -> float:
    """The teacher's insertion in physics: the deepest the stick's lower end went into the glass
    over demonstration ``demo`` of ``motion``, below the rim [m] (0: never in it).

    The scene with the teacher holding both objects on its hands' welds and the robot at rest;
    the hands (mocap bodies) follow the script at every physics step from the demonstration's
    start, and the stick and the glass touch as in the robot's replays. A check of the script,
    not part of a run.

    Raises:
        ImitateError: ``demo`` is not a demonstration of ``motion``.
    """
    if not 0 <= demo < len(motion.boundaries):
        raise ImitateError(f"demo={demo!r} not accepted: 0..{len(motion.boundaries) - 1}")
    model = build_model(SceneConfig(
        teacher=True, holder="teacher", objects=SCRIPT.objects,
        grasps=tuple(shapes.GRASP[obj] for obj in SCRIPT.objects),
    ))
    data = mujoco.MjData(model)
    joints = [model.joint(j).qposadr[0] for j in humanoid.JOINTS]
    data.qpos[joints] = data.ctrl[:] = humanoid.rest_pose()
    start, end = motion.boundaries[demo]
    poses = motion.poses(np.arange(start, end, model.opt.timestep))
    hands = {
        obj: model.body_mocapid[model.body(teacher.HAND[holding_side(model, obj)]).id]
        for obj in SCRIPT.objects
    }
    deepest = 0.0
    for step in range(len(poses[objects.STICK][0])):
        for obj, mocap in hands.items():
            data.mocap_pos[mocap], data.mocap_quat[mocap] = hand_pose_for_object(
                model, obj, poses[obj][0][step], poses[obj][1][step]
            )
        if step == 0:  # the objects into the hands
            hold(model, data, "teacher")
            mujoco.mj_forward(model, data)
        mujoco.mj_step(model, data)
        deepest = max(deepest, stick_end(data)[2])
    return deepest


def demonstrated(motion: TeacherMotion, demo: int) -> bool:
    """Whether demonstration ``demo`` of ``motion`` puts the stick into the glass in physics
    (:func:`teacher_insert`), as deep as a reproduction must."""
    return inserted(teacher_insert(motion, demo))
