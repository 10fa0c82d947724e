"""The robot watches the teacher: its head cameras and the stereo pairs they see.

:func:`session` scripts a recording session (:mod:`imitate.envs.teacher_motion`) in the scene
where the robot stands in its rest pose with its head turned towards the teacher's hands, the
objects held by the teacher; :func:`frames` renders it from the robot's two head cameras at
camera rate. The cameras' parameters are plain arrays (:func:`camera_parameters`), and
:func:`tracked_point` gives the objects' true tracked points, for evaluating a tracker.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field

import mujoco
import numpy as np
from scipy.spatial.transform import Rotation

from imitate.envs import mannequin, tasks, teacher_motion
from imitate.envs.assembly import SceneConfig, build_model, hold
from imitate.envs.rendering import in_thread, make_renderer
from imitate.errors import ImitateError
from imitate.models import humanoid, objects, shapes

EYES = (humanoid.LEFT_EYE, humanoid.RIGHT_EYE)


@dataclass(frozen=True)
class ObservationConfig:
    """How the robot watches.

    Attributes:
        teacher: the demonstrations.
        fps: camera rate [Hz].
        width: image width [px].
        height: image height [px].
        head_tilt: the robot's head tilt while watching [rad] (> 0 looks down); the default
            centres the teacher's hands in the images.
        fast_render: render the eye cameras without shadows, reflections, multisample
            anti-aliasing, skybox and textures (a black sky, a plain floor): several times
            faster on a CPU (Mesa llvmpipe; the skybox alone is a third of a frame), and the
            tracker's colour masks are the same (it sees the objects and the teacher's skin,
            not the background); ``False`` renders as the scene is set.
    """

    teacher: teacher_motion.TeacherConfig = field(default_factory=teacher_motion.TeacherConfig)
    fps: float = 30.0
    width: int = 640
    height: int = 480
    head_tilt: float = 0.08
    fast_render: bool = True

    def __post_init__(self):
        if not self.fps > 0:
            raise ImitateError(f"fps={self.fps!r} not accepted: a camera rate > 0 Hz")
        if not (isinstance(self.width, int) and isinstance(self.height, int)):
            raise ImitateError(
                f"image size {self.width!r}x{self.height!r} not accepted: integers [px]"
            )


def watching_scene(config: ObservationConfig) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The scene with the teacher holding its task's objects and the robot at rest, looking at
    them."""
    script = tasks.module(config.teacher.task, "teacher").SCRIPT
    model = build_model(SceneConfig(
        teacher=True, holder="teacher", objects=script.objects,
        grasps=tuple(shapes.GRASP[obj] for obj in script.objects), places=script.places,
    ))
    data = mujoco.MjData(model)
    pose = dict(zip(humanoid.JOINTS, humanoid.rest_pose(), strict=True))
    pose["head_tilt"] = config.head_tilt
    for joint, angle in pose.items():
        data.qpos[model.joint(joint).qposadr[0]] = angle
    hold(model, data, "teacher")
    mujoco.mj_forward(model, data)
    return model, data


def tracked_point(obj: str, pos: np.ndarray, quat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The true tracked point (axis centre at half height) and unit axis of ``obj``.

    Args:
        obj: object name.
        pos: ``(n, 3)`` frame positions (bottom centre) [m].
        quat: ``(n, 4)`` frame orientations, wxyz.

    Returns:
        ``(point (n, 3) [m], axis (n, 3))``.
    """
    axis = Rotation.from_quat(quat, scalar_first=True).as_matrix()[:, :, 2]
    return pos + axis * objects.SHAPES[obj].height / 2, axis


def camera_parameters(
    model: mujoco.MjModel, data: mujoco.MjData, camera: str, width: int, height: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The pinhole parameters of MuJoCo camera ``camera`` rendering ``width x height`` images.

    Uses the camera's pose in ``data`` (after kinematics) and its vertical field of view
    ``cam_fovy``; MuJoCo's pixels are square and its optical axis passes through the image
    centre, between the two middle pixels.

    Returns:
        ``(intrinsics (3, 3) [px], rotation (3, 3), position (3,) [m])`` in OpenCV's
        convention (x right, y down, z forward): ``K`` (a pixel's centre is at its index
        ``(col, row)``), the world-to-camera rotation (rows: the camera axes in world
        coordinates) and the optical centre in the world frame.

    Raises:
        ImitateError: no camera of that name; the message lists the model's cameras.
    """
    cam_id = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
    if cam_id < 0:
        names = [model.camera(i).name for i in range(model.ncam)]
        raise ImitateError(f"camera {camera!r} not in the model; its cameras: {names}")
    focal = 0.5 * height / np.tan(np.radians(model.cam_fovy[cam_id]) / 2)
    intrinsics = np.array(
        [[focal, 0.0, (width - 1) / 2], [0.0, focal, (height - 1) / 2], [0.0, 0.0, 1.0]]
    )
    # MuJoCo's camera frame: x right, y up, looking along -z; OpenCV's: y down, z forward.
    rotation = (data.cam_xmat[cam_id].reshape(3, 3) * np.array([1.0, -1.0, -1.0])).T
    return intrinsics, rotation, data.cam_xpos[cam_id].copy()


@dataclass(frozen=True, eq=False)
class Session:
    """A recording session to render, frame by frame.

    Attributes:
        motion: the teacher's motion.
        times: ``(n,)`` frame times [s].
        cameras: the left and right eyes' :func:`camera_parameters`.
        width: image width [px].
        height: image height [px].
        model: the scene.
        data: its data (the robot's pose; objects and arms are set per frame).
        fast_render: shadows and reflections off (see :class:`ObservationConfig`).
    """

    motion: teacher_motion.TeacherMotion
    times: np.ndarray
    cameras: tuple[tuple[np.ndarray, np.ndarray, np.ndarray], ...]
    width: int
    height: int
    model: mujoco.MjModel
    data: mujoco.MjData
    fast_render: bool = False


def session(config: ObservationConfig = ObservationConfig()) -> Session:
    """Script the teacher's motion and set up the scene and cameras for rendering it."""
    motion = teacher_motion.script_demonstrations(config.teacher)
    model, data = watching_scene(config)
    cameras = tuple(
        camera_parameters(model, data, eye, config.width, config.height) for eye in EYES
    )
    times = np.arange(0.0, motion.duration, 1.0 / config.fps)
    if config.fast_render:
        model.vis.quality.offsamples = 0  # read when the renderer's context is made
    return Session(
        motion, times, cameras, config.width, config.height, model, data, config.fast_render,
    )


def frames(
    sess: Session, timing: dict | None = None, ahead: bool = True
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Render the session's stereo pairs, one per frame time, in order.

    With ``ahead`` a thread renders them, with its own OpenGL context, up to
    :data:`RENDER_AHEAD` pairs ahead of the caller, which meanwhile consumes the earlier ones,
    e.g. tracks them (MuJoCo's rendering, OpenCV and the tracker's kernels release the GIL):
    the pairs are the same, bit for bit, as those rendered in the calling thread
    (``ahead=False``), and they come in the same order.

    Args:
        sess: the session.
        timing: if given, ``timing["render"]`` accumulates the rendering time [s].
        ahead: render in a thread, ahead of the caller.

    Yields:
        ``(left, right)`` RGB images ``(height, width, 3)`` uint8.

    Raises:
        ImitateError: no OpenGL context.
    """
    if not ahead:
        for pair in _rendered(sess, timing):
            yield pair[0], pair[1]
        return
    with in_thread(lambda: _rendered(sess, timing), RENDER_AHEAD) as pairs:
        for pair in pairs:
            yield pair[0], pair[1]


# Pairs rendered ahead of the caller at most: enough to smooth out uneven frames, little memory
# (8 pairs of 640x480 are 15 MB).
RENDER_AHEAD = 8


def _rendered(sess: Session, timing: dict | None) -> Iterator[np.ndarray]:
    """The session's pairs ``(2, height, width, 3)`` uint8, rendered in the calling thread."""
    eyes = _eye_renderer(sess)
    poses = {**sess.motion.poses(sess.times), **sess.motion.place_poses(sess.times)}
    try:
        for i in range(len(sess.times)):
            start = time.perf_counter()
            pair = np.empty((2, sess.height, sess.width, 3), np.uint8)
            _render_pair(sess, eyes, poses, i, pair)
            if timing is not None:
                timing["render"] = timing.get("render", 0.0) + time.perf_counter() - start
            yield pair
    finally:
        eyes[0].close()


def _eye_renderer(sess: Session) -> tuple[mujoco.Renderer, mujoco.MjvOption]:
    """The eyes' renderer and visualisation options (see ``fast_render``)."""
    fast = sess.fast_render
    renderer = make_renderer(sess.model, sess.height, sess.width, shadows=not fast)
    for flag in (mujoco.mjtRndFlag.mjRND_REFLECTION, mujoco.mjtRndFlag.mjRND_SKYBOX):
        renderer.scene.flags[flag] = not fast
    option = mujoco.MjvOption()
    option.flags[mujoco.mjtVisFlag.mjVIS_TEXTURE] = not fast
    return renderer, option


def _render_pair(sess: Session, eyes, poses: dict, i: int, out: np.ndarray) -> None:
    """Render frame ``i`` of ``sess`` (object ``poses`` at all its times) with ``eyes``
    (:func:`_eye_renderer`) into ``out`` ``(2, height, width, 3)`` uint8."""
    renderer, option = eyes
    mannequin.show(
        sess.model, sess.data, {obj: (p[i], q[i]) for obj, (p, q) in poses.items()}
    )
    for k, eye in enumerate(EYES):
        renderer.update_scene(sess.data, camera=eye, scene_option=option)
        renderer.render(out=out[k])
