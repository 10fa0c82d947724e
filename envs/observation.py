"""The robot watches the teacher: stereo frames from its head cameras, tracked into observations.

:func:`observe` scripts a recording session (:mod:`imitate.envs.teacher_motion`), renders it
from the robot's two head cameras at camera rate, runs the stereo tracker
(:mod:`imitate.perception`) on every pair and keeps the ground truth beside the tracks for
evaluation. The robot stands in its rest pose with its head turned towards the teacher's hands;
the objects are held by the teacher.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from dataclasses import dataclass, field

import cv2
import mujoco
import numpy as np
from imitate.envs import teacher_motion
from imitate.envs.assembly import SceneConfig, build_model, hold
from imitate.envs.rendering import make_renderer
from imitate.models import humanoid, objects
from scipy.spatial.transform import Rotation

from imitate.errors import ImitateError
from imitate.perception import (
    ColourRange,
    GroundTruth,
    ObjectModel,
    Observations,
    PerceptionConfig,
    StereoTracker,
    axis_angle,
    gaze_frame,
    mujoco_camera,
    tracks_from_ends,
)

SHAPES = {objects.BOTTLE: objects.BOTTLE_SHAPE, objects.GLASS: objects.GLASS_SHAPE}


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
        fast_render: render the eye cameras without shadows, reflections and multisample
            anti-aliasing: about 5x faster on a CPU (Mesa llvmpipe), tracking as accurate
            (the colour thresholds do not need them); ``False`` renders as the scene is set.
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


def colour_range(rgba, hue_tolerance: int = 12) -> ColourRange:
    """HSV range of a uniformly coloured, shaded surface of colour ``rgba``.

    Hue within ``hue_tolerance`` (OpenCV half-degrees) of the colour's, saturation from 100
    (shading keeps it; the grey and skin of the scene stay below), any value from 30.
    """
    pixel = np.uint8(np.round(np.array(rgba[:3]) * 255))[None, None]
    hue = int(cv2.cvtColor(pixel, cv2.COLOR_RGB2HSV)[0, 0, 0])
    return ColourRange(
        ((hue - hue_tolerance) % 180, 100, 30), ((hue + hue_tolerance) % 180, 255, 255)
    )


def object_models() -> tuple[ObjectModel, ...]:
    """The bottle and glass as the robot knows them: colour range and outer radius profile."""
    return tuple(
        ObjectModel(
            name=name,
            colour=colour_range(shape.rgba),
            profile=tuple((r + shape.wall / 2, h) for r, h in shape.profile),
        )
        for name, shape in SHAPES.items()
    )


def perception_config(**overrides) -> PerceptionConfig:
    """The tracker's settings for this scene (``overrides`` replace any field)."""
    return PerceptionConfig(objects=object_models(), **overrides)


def watching_scene(config: ObservationConfig) -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The scene with the teacher holding the objects and the robot at rest, looking at them."""
    model = build_model(SceneConfig(teacher=True, particles=0, holder="teacher"))
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
    return pos + axis * SHAPES[obj].height / 2, axis


@dataclass(frozen=True, eq=False)
class Session:
    """A rendered recording session, frame by frame.

    Attributes:
        motion: the teacher's motion.
        times: ``(n,)`` frame times [s].
        cameras: left and right :class:`imitate.perception.PinholeCamera`.
        model: the scene.
        data: its data (the robot's pose; objects and arms are set per frame).
        fast_render: shadows and reflections off (see :class:`ObservationConfig`).
    """

    motion: teacher_motion.TeacherMotion
    times: np.ndarray
    cameras: tuple
    model: mujoco.MjModel
    data: mujoco.MjData
    fast_render: bool = False


def session(config: ObservationConfig = ObservationConfig()) -> Session:
    """Script the teacher's motion and set up the scene and cameras for rendering it."""
    motion = teacher_motion.script_demonstrations(config.teacher)
    model, data = watching_scene(config)
    cameras = tuple(
        mujoco_camera(model, data, eye, config.width, config.height)
        for eye in (humanoid.LEFT_EYE, humanoid.RIGHT_EYE)
    )
    times = np.arange(0.0, motion.duration, 1.0 / config.fps)
    if config.fast_render:
        model.vis.quality.offsamples = 0  # read when the renderer's context is made
    return Session(motion, times, cameras, model, data, config.fast_render)


def frames(sess: Session, timing: dict | None = None) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """Render the session's stereo pairs, one per frame time.

    Args:
        sess: the session.
        timing: if given, ``timing["render"]`` accumulates the rendering time [s].

    Yields:
        ``(left, right)`` RGB images ``(height, width, 3)`` uint8.
    """
    left_cam = sess.cameras[0]
    renderer = make_renderer(
        sess.model, left_cam.height, left_cam.width, shadows=not sess.fast_render
    )
    renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = not sess.fast_render
    poses = sess.motion.poses(sess.times)
    try:
        for i in range(len(sess.times)):
            start = time.perf_counter()
            teacher_motion.show(
                sess.model, sess.data, {obj: (p[i], q[i]) for obj, (p, q) in poses.items()}
            )
            pair = []
            for eye in (humanoid.LEFT_EYE, humanoid.RIGHT_EYE):
                renderer.update_scene(sess.data, camera=eye)
                pair.append(renderer.render())
            if timing is not None:
                timing["render"] = timing.get("render", 0.0) + time.perf_counter() - start
            yield pair[0], pair[1]
    finally:
        renderer.close()


def ground_truth(sess: Session, names: tuple[str, ...]) -> GroundTruth:
    """True tracked points, axes and angles of ``names`` at the session's frame times."""
    poses = sess.motion.poses(sess.times)
    gaze = gaze_frame(sess.cameras[0])
    points, axes = zip(*(tracked_point(name, *poses[name]) for name in names), strict=True)
    axis = np.array(axes)
    return GroundTruth(
        position=np.array(points),
        axis=axis,
        angle=np.unwrap(axis_angle(axis, gaze), axis=-1),
        boundaries=sess.motion.boundaries.copy(),
    )


def observe(
    config: ObservationConfig = ObservationConfig(),
    perception: PerceptionConfig | None = None,
    timing: dict | None = None,
    progress: bool = False,
) -> Observations:
    """Render the teacher's session from the robot's eyes and track the objects.

    Args:
        config: session and cameras.
        perception: tracker settings; :func:`perception_config` by default.
        timing: if given, receives ``"render"`` and ``"track"`` (tracking and triangulation)
            totals [s] and ``"pairs"``.
        progress: show a progress bar.

    Returns:
        Tracks, camera matrices and ground truth.
    """
    perception = perception or perception_config()
    sess = session(config)
    tracker = StereoTracker(*sess.cameras, perception)
    timing = {} if timing is None else timing
    ends = np.full((len(perception.objects), len(sess.times), 2, 3), np.nan)
    pairs = frames(sess, timing)
    if progress:
        from tqdm import tqdm

        pairs = tqdm(pairs, total=len(sess.times), desc="observe", unit="pair")
    track_time = 0.0
    for i, (left, right) in enumerate(pairs):
        start = time.perf_counter()
        result = tracker.update(left, right)
        track_time += time.perf_counter() - start
        for k, obj in enumerate(perception.objects):
            if result[obj.name] is not None:
                ends[k, i] = result[obj.name].ends
    timing["track"] = track_time
    timing["pairs"] = len(sess.times)
    tracks = tracks_from_ends(
        sess.times, perception.objects, ends, gaze_frame(sess.cameras[0]), perception
    )
    return Observations(
        tracks=tracks,
        projections=np.array([cam.projection for cam in sess.cameras]),
        image_size=(config.width, config.height),
        truth=ground_truth(sess, tracks.objects),
    )
