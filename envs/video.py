"""The run's video: the teacher demonstrating, then the robot pouring, from the overview camera.

Frames are rendered from kinematic states only (no physics here): the teacher's scripted object
poses (:mod:`imitate.envs.teacher_motion`) and the states a replay recorded
(:class:`StateRecorder`). Shadows are off by default: on a CPU (Mesa) they are costly.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from pathlib import Path

import cv2
import imageio.v2 as imageio
import mujoco
import numpy as np

from imitate.artifacts import write_atomic
from imitate.envs import teacher_motion
from imitate.envs.assembly import SceneConfig, build_model
from imitate.envs.observation import ObservationConfig, watching_scene
from imitate.envs.pouring import PouringEnv
from imitate.envs.rendering import make_renderer
from imitate.models import scene as scene_names

CLOSE_UP_LOOKAT = (0.25, 0.0, 0.9)  # between the robot's hands at the start [m]


class StateRecorder:
    """``on_step`` hook for :func:`imitate.replay.replay`: keeps the kinematic state every
    ``every`` env steps (``qpos`` and the teacher's mocap poses), enough to render it again."""

    def __init__(self, every: int = 1):
        self.every, self._calls = max(1, int(every)), 0
        self.qpos, self.mocap_pos, self.mocap_quat = [], [], []

    def __call__(self, env: PouringEnv) -> None:
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
    motion: teacher_motion.TeacherMotion, times: np.ndarray, width: int, height: int
) -> Iterator[np.ndarray]:
    """The teacher's session at ``times`` [s], robot watching: ``(height, width, 3) uint8``."""
    model, data = watching_scene(ObservationConfig())
    renderer = make_renderer(model, height, width, shadows=False)
    try:
        for t in times:
            poses = motion.poses(np.array([t]))
            teacher_motion.show(model, data, {obj: (p[0], q[0]) for obj, (p, q) in poses.items()})
            renderer.update_scene(data, scene_names.OVERVIEW)
            yield renderer.render()
    finally:
        renderer.close()


def replay_frames(
    config: SceneConfig,
    states: dict[str, np.ndarray],
    width: int,
    height: int,
    camera: str | mujoco.MjvCamera = scene_names.OVERVIEW,
    shadows: bool = False,
) -> Iterator[np.ndarray]:
    """Recorded replay ``states`` (:meth:`StateRecorder.arrays`) of the scene ``config``, seen
    from ``camera`` (a named camera or a free one, see :func:`close_up`)."""
    model = build_model(config)
    data = mujoco.MjData(model)
    renderer = make_renderer(model, height, width, shadows=shadows)
    try:
        for qpos, mocap_pos, mocap_quat in zip(
            states["qpos"], states["mocap_pos"], states["mocap_quat"], strict=True
        ):
            data.qpos[:], data.mocap_pos[:], data.mocap_quat[:] = qpos, mocap_pos, mocap_quat
            mujoco.mj_kinematics(model, data)
            mujoco.mj_camlight(model, data)
            renderer.update_scene(data, camera)
            yield renderer.render()
    finally:
        renderer.close()


def close_up() -> mujoco.MjvCamera:
    """A free camera on the robot's hands, from its front left (paper Fig. 8's view)."""
    camera = mujoco.MjvCamera()
    camera.type = mujoco.mjtCamera.mjCAMERA_FREE
    camera.lookat[:] = CLOSE_UP_LOOKAT
    camera.distance, camera.azimuth, camera.elevation = 1.1, 215.0, -18.0
    return camera


def captioned(frames: Iterable[np.ndarray], text: str) -> Iterator[np.ndarray]:
    """``frames`` with ``text`` written in their top-left corner."""
    for rendered in frames:
        frame = np.ascontiguousarray(rendered)
        scale = frame.shape[0] / 480
        org = (int(12 * scale) + 1, int(30 * scale) + 8)
        for colour, thickness in (((0, 0, 0), 4), ((255, 255, 255), 1)):
            cv2.putText(frame, text, org, cv2.FONT_HERSHEY_SIMPLEX, 0.7 * scale, colour,
                        max(1, int(thickness * scale)), cv2.LINE_AA)
        yield frame


def write_video(path: Path, frames: Iterable[np.ndarray], fps: float) -> int:
    """Encode ``frames`` as H.264 mp4 at ``fps``, atomically; returns the number of frames."""
    count = 0

    def write(tmp: Path) -> None:
        nonlocal count
        writer = imageio.get_writer(tmp, fps=fps, codec="libx264", macro_block_size=8)
        try:
            for frame in frames:
                writer.append_data(frame)
                count += 1
        finally:
            writer.close()

    write_atomic(path, write)
    return count
