"""The run's video and snapshots: the teacher demonstrating, then the robot doing the task.

Frames are rendered from kinematic states only (no physics here): the teacher's scripted object
poses (:mod:`imitate.envs.teacher_motion`) and the states a replay recorded
(:class:`StateRecorder`). The teacher is seen from above the robot's left shoulder, with the
robot's own eye view inset; the robot from the teacher's side, where what goes into the target
shows.
Shadows are off by default: on a CPU (Mesa) they are costly; ``quick=True`` also leaves out
multisampling and reflections, which cost most of a frame's time there (the run's video).
"""

from __future__ import annotations

import dataclasses
import errno
import os
from collections.abc import Iterable, Iterator
from contextlib import closing
from pathlib import Path
from typing import Any

import cv2
import imageio.v2 as imageio
import mujoco
import numpy as np

from imitate.envs import mannequin, teacher_motion
from imitate.envs.assembly import SceneConfig, build_model, clearance_geoms
from imitate.envs.bimanual import BimanualEnv
from imitate.envs.collision import CollisionPairs, signed_distances
from imitate.envs.observation import ObservationConfig, watching_scene
from imitate.envs.rendering import interleaved, make_renderer
from imitate.models import humanoid
from imitate.models import scene as scene_names

# The target is drawn translucent, so what goes into it shows; only the copy of the model that
# draws it is changed (as the scene's contents change theirs: Content.show).
TARGET_DRAWN_ALPHA = 0.3
MARK_RGB = (255, 230, 0)  # tracked objects in the robot's eye view
CAPTION_BOX_RGB = (24, 24, 28)
FONT = cv2.FONT_HERSHEY_SIMPLEX


class StateRecorder:
    """``on_step`` hook for :func:`imitate.motion.replay.replay`: keeps the kinematic state every
    ``every`` env steps (``qpos`` and the teacher's mocap poses), enough to render it again."""

    def __init__(self, every: int = 1):
        self.every, self._calls = max(1, int(every)), 0
        self.qpos: list[np.ndarray] = []
        self.mocap_pos: list[np.ndarray] = []
        self.mocap_quat: list[np.ndarray] = []

    def __call__(self, env: BimanualEnv) -> None:
        if self._calls % self.every == 0:
            self.qpos.append(env.data.qpos.copy())
            self.mocap_pos.append(env.data.mocap_pos.copy())
            self.mocap_quat.append(env.data.mocap_quat.copy())
        self._calls += 1

    def arrays(self) -> dict[str, np.ndarray]:
        """``{"qpos": (n, nq), "mocap_pos": (n, nmocap, 3), "mocap_quat": (n, nmocap, 4)}``."""
        return {
            "qpos": np.array(self.qpos),
            "mocap_pos": np.array(self.mocap_pos),
            "mocap_quat": np.array(self.mocap_quat),
        }


def teacher_frames(
    motion: teacher_motion.TeacherMotion,
    times: np.ndarray,
    width: int,
    height: int,
    marks: np.ndarray | None = None,
    projection: np.ndarray | None = None,
    image_size: tuple[int, int] | None = None,
    threads: int = 1,
    quick: bool = False,
) -> Iterator[np.ndarray]:
    """The teacher's session at ``times`` [s] over the robot's shoulder, and the robot's left-eye
    view inset in the top-right corner: ``(height, width, 3) uint8``.

    Args:
        motion: the scripted session whose object poses are shown.
        times: ``(n,)`` instants of the session [s], one frame each.
        width: frame width [px].
        height: frame height [px].
        marks: ``(len(times), k, 2, 3)`` world points [m]: ``k`` segments (the tracked objects'
            axes) drawn on the eye view; NaN ones are skipped.
        projection: ``(3, 4)`` the left eye's projection matrix for images of ``image_size``
            ``(width, height)`` [px], which the marks are projected with.
        image_size: ``(width, height)`` [px] of the images ``projection`` is for; needed with
            ``marks``.
        threads: render in this many threads at once (:func:`interleaved`); the same frames.
        quick: no multisampling nor reflections (:func:`frame_renderer`).
    """

    def part(every: slice) -> Iterator[np.ndarray]:
        model, data = watching_scene(ObservationConfig(teacher=motion.config))
        inset_size = (2 * (width // 6), 2 * (height // 6))
        renderer = frame_renderer(model, height, width, quick=quick)
        model.vis.quality.offsamples = 0  # the eye as the robot saw (fast_render): 2x faster
        eye = frame_renderer(model, inset_size[1], inset_size[0], quick=quick)
        try:
            for i in range(len(times))[every]:
                at = times[i : i + 1]
                poses = {**motion.poses(at), **motion.place_poses(at)}
                mannequin.show(
                    model, data, {obj: (p[0], q[0]) for obj, (p, q) in poses.items()}
                )
                renderer.update_scene(data, scene_names.TEACHER_VIEW)
                frame = renderer.render()
                eye.update_scene(data, humanoid.LEFT_EYE)
                view = eye.render()
                if marks is not None:
                    _draw_marks(view, marks[i], projection, image_size)
                yield _inset(frame, view)
        finally:
            renderer.close()
            eye.close()

    return interleaved(part, threads)


def _draw_marks(view: np.ndarray, segments: np.ndarray, projection, image_size) -> None:
    """Draw ``segments`` ``(k, 2, 3)`` [m] projected by ``projection`` (for ``image_size``) on
    ``view``, rescaled to its size."""
    (w, h), (vw, vh) = image_size, (view.shape[1], view.shape[0])
    scale = vh / h  # MuJoCo's field of view is vertical; the optical axis is the centre
    radius, thickness = max(2, vh // 32), max(1, vh // 80)
    for segment in segments:
        if not np.isfinite(segment).all():
            continue
        pix = np.c_[segment, np.ones(2)] @ np.asarray(projection).T
        pix = (pix[:, :2] / pix[:, 2:] - ((w - 1) / 2, (h - 1) / 2)) * scale
        a, b = np.round(pix + ((vw - 1) / 2, (vh - 1) / 2)).astype(int)
        cv2.line(view, tuple(a), tuple(b), MARK_RGB, thickness, cv2.LINE_AA)
        cv2.circle(view, tuple((a + b) // 2), radius, MARK_RGB, thickness, cv2.LINE_AA)


def _inset(frame: np.ndarray, view: np.ndarray) -> np.ndarray:
    """``view`` pasted into the top-right corner of ``frame``, framed in white."""
    margin = max(2, frame.shape[0] // 60)
    h, w = view.shape[:2]
    x0, y0 = frame.shape[1] - margin - w, margin
    cv2.rectangle(frame, (x0 - 2, y0 - 2), (x0 + w + 1, y0 + h + 1), (255, 255, 255), -1)
    frame[y0 : y0 + h, x0 : x0 + w] = view
    return frame


def replay_frames(
    config: SceneConfig,
    states: dict[str, np.ndarray],
    width: int,
    height: int,
    camera: str = scene_names.POUR_VIEW,
    shadows: bool = False,
    threads: int = 1,
    quick: bool = False,
) -> Iterator[np.ndarray]:
    """Recorded replay ``states`` (:meth:`StateRecorder.arrays`) of the scene ``config``, seen
    from ``camera``, drawn so that what goes into the target shows (:func:`_show`); in ``threads``
    threads at once (:func:`interleaved`), the same frames; ``quick``: see
    :func:`frame_renderer`."""
    config = _as_recorded(config, states)

    def part(every: slice) -> Iterator[np.ndarray]:
        model = build_model(config)
        _show(model, config)
        data = mujoco.MjData(model)
        renderer = frame_renderer(model, height, width, shadows=shadows, quick=quick)
        try:
            for state in _states({name: value[every] for name, value in states.items()}):
                _pose(model, data, *state)
                mujoco.mj_camlight(model, data)
                renderer.update_scene(data, camera)
                yield renderer.render()
        finally:
            renderer.close()

    return interleaved(part, threads)


def frame_renderer(
    model: mujoco.MjModel, height: int, width: int, shadows: bool = False, quick: bool = False
) -> mujoco.Renderer:
    """:func:`~imitate.envs.rendering.make_renderer`'s renderer; with ``quick``, without
    multisampling (``model``'s ``offsamples`` set to 0) and reflections: on a CPU (Mesa
    llvmpipe) a 640x480 frame of the pour takes about a third of the time, its edges a little
    jagged, its look otherwise the same."""
    if quick:
        model.vis.quality.offsamples = 0
    renderer = make_renderer(model, height, width, shadows=shadows)
    if quick:
        renderer.scene.flags[mujoco.mjtRndFlag.mjRND_REFLECTION] = False
    return renderer


def penetrations(
    config: SceneConfig, states: dict[str, np.ndarray]
) -> list[tuple[float, tuple[str, str]]]:
    """Per recorded state, the smallest signed distance [m] between geoms that must not touch
    (as the task env measures it) and the names of that pair."""
    model = build_model(_as_recorded(config, states))
    data = mujoco.MjData(model)
    pairs = CollisionPairs.between(model, clearance_geoms(model))
    found = []
    for state in _states(states):
        _pose(model, data, *state)
        dist, _ = signed_distances(model, data, pairs)
        k = int(np.argmin(dist))
        found.append((float(dist[k]), pairs.names(model, k)))
    return found


def _as_recorded(config: SceneConfig, states: dict[str, np.ndarray]) -> SceneConfig:
    """``config`` with the teacher where the ``states`` have its mocap poses (the task env
    has it only with ``teacher=True``)."""
    return dataclasses.replace(config, teacher=states["mocap_pos"].shape[1] > 0)


def _states(states: dict[str, np.ndarray]):
    return zip(states["qpos"], states["mocap_pos"], states["mocap_quat"], strict=True)


def _pose(model, data, qpos, mocap_pos, mocap_quat) -> None:
    data.qpos[:], data.mocap_pos[:], data.mocap_quat[:] = qpos, mocap_pos, mocap_quat
    mujoco.mj_kinematics(model, data)


def _show(model: mujoco.MjModel, config: SceneConfig) -> None:
    """Draw the target translucent and the scene's contents as they show themselves, in
    ``model`` (of ``config``, a copy for drawing only)."""
    model.geom_rgba[model.geom(f"{config.objects[1]}_visual").id, 3] = TARGET_DRAWN_ALPHA
    for content in config.contents:
        content.show(model)


def caption_layout(width: int, height: int, text: str):
    """Where :func:`caption` writes ``text`` on a ``width x height`` frame.

    Returns:
        ``(box, org, scale, thickness)``: the caption box ``(x0, y0, x1, y1)`` [px, inclusive],
        the text's origin (bottom left) and OpenCV's font scale and line thickness; the text
        shrinks to fit the width (illegible below 0.35, about 8 px high).
    """
    unit = height / 480
    margin, pad = max(1, round(8 * unit)), max(2, round(6 * unit))
    scale, thickness = max(0.62 * unit, 0.4), max(1, round(1.5 * unit))
    text_width = cv2.getTextSize(text, FONT, scale, thickness)[0][0]
    scale *= min(1.0, (width - 2 * margin - 2 * pad) / text_width)
    (text_width, text_height), baseline = cv2.getTextSize(text, FONT, scale, thickness)
    x0, y0 = margin, margin
    box = (x0, y0, x0 + text_width + 2 * pad, y0 + text_height + baseline + 2 * pad)
    return box, (x0 + pad, y0 + pad + text_height), scale, thickness


def caption(frame: np.ndarray, text: str) -> np.ndarray:
    """``frame`` with ``text`` in white on a dark box in its top-left corner (written once, so
    it reads the same with any OpenCV version)."""
    frame = np.array(frame)  # a copy: OpenCV draws in place
    box, org, scale, thickness = caption_layout(frame.shape[1], frame.shape[0], text)
    cv2.rectangle(frame, box[:2], box[2:], CAPTION_BOX_RGB, -1)
    cv2.putText(frame, text, org, FONT, scale, (255, 255, 255), thickness, cv2.LINE_AA)
    return frame


def caption_error(frame: np.ndarray, text: str) -> float:
    """Mean absolute difference (0..255) between the caption box of ``frame`` (a decoded video
    frame, say) and the box :func:`caption` draws for ``text``: small when the caption reads as
    written, large when it is missing, garbled or elsewhere."""
    x0, y0, x1, y1 = caption_layout(frame.shape[1], frame.shape[0], text)[0]
    inside = (slice(y0, y1 + 1), slice(x0, x1 + 1))
    reference = caption(np.zeros_like(frame), text)
    return float(np.abs(frame[inside].astype(int) - reference[inside].astype(int)).mean())


def captioned(frames: Iterable[np.ndarray], text: str) -> Iterator[np.ndarray]:
    """``frames`` with ``text`` in their top-left corner (:func:`caption`)."""
    for frame in frames:
        yield caption(frame, text)


# x264's veryfast preset at imageio's quality 6 (of 10): less encoding time than imageio's default
# (the medium preset at quality 5) at a higher PSNR, in larger files (scripts/bench/bench_video.py).
ENCODER: dict[str, Any] = {
    "codec": "libx264", "quality": 6, "ffmpeg_params": ["-preset", "veryfast"],
}


def write_video(path: Path, frames: Iterable[np.ndarray], fps: float) -> int:
    """Encode ``frames`` as H.264 mp4 at ``fps`` (:data:`ENCODER`) into ``path`` (the caller's:
    a temporary file it renames into place, say), deleted again if the encoding fails; returns
    the number of frames.

    Raises:
        OSError: the encoding failed; ``ENOSPC`` naming ``path`` if the disk is full (where
            ffmpeg's broken pipe would hide it).
    """
    path = Path(path)
    count = 0
    try:
        with closing(imageio.get_writer(path, fps=fps, macro_block_size=8, **ENCODER)) as w:
            for frame in frames:
                w.append_data(frame)
                count += 1
    except BaseException as err:
        path.unlink(missing_ok=True)
        if isinstance(err, OSError) and _full(path.parent):  # ffmpeg stopped: a full disk?
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path)) from err
        raise
    return count


def _full(folder: Path) -> bool:
    """Whether the file system of ``folder`` has no block or no inode left for this user."""
    fs = os.statvfs(folder)
    return fs.f_bavail == 0 or fs.f_favail == 0
