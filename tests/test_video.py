"""What a viewer sees: captions that read with any OpenCV version, the liquid in the video, and
the same frames whether one thread renders them or several."""

import threading

import cv2
import imageio.v3 as iio
import mujoco
import numpy as np
import pytest

from imitate.envs.assembly import build_model
from imitate.envs.observation import camera_parameters
from imitate.envs.pour.liquid import PARTICLE_RGBA
from imitate.envs.rendering import interleaved
from imitate.envs.teacher_motion import script_demonstrations
from imitate.envs.video import (
    CAPTION_BOX_RGB,
    FONT,
    caption,
    caption_error,
    caption_layout,
    replay_frames,
    teacher_frames,
)
from imitate.errors import ImitateError
from imitate.models import objects
from imitate.models import scene as scene_names
from imitate.stages.config import load_config
from imitate.stages.figures import ROBOT_CAPTION, TEACHER_CAPTION
from imitate.stages.files import ReplayFile

LONG = "teacher demonstrates (3x); inset: robot's eye, tracking"


@pytest.mark.parametrize(
    ("width", "height", "text"),
    [(160, 120, "CI video"), (320, 240, LONG), (640, 480, LONG), (1280, 720, LONG)],
)
def test_caption_is_white_text_once_on_its_box(width, height, text):
    frame = np.random.default_rng(0).integers(60, 200, (height, width, 3), dtype=np.uint8)
    drawn = caption(frame.copy(), text)
    (x0, y0, x1, y1), org, scale, thickness = caption_layout(width, height, text)
    changed = np.argwhere((drawn != frame).any(axis=2))
    assert changed[:, 1].min() >= x0 and changed[:, 1].max() <= x1 <= width - 1
    assert changed[:, 0].min() >= y0 and changed[:, 0].max() <= y1 <= height - 1
    box = drawn[y0 : y1 + 1, x0 : x1 + 1].astype(int)
    white = (box > 200).all(axis=2)
    dark = (np.abs(box - CAPTION_BOX_RGB) <= 2).all(axis=2)
    assert 0.03 < white.mean() < 0.5 and dark.mean() > 0.4
    assert scale >= 0.35  # letters at least 8 px high
    # Every white pixel lies inside the text's own extent (OpenCV's getTextSize for the same
    # font, scale and thickness): no shadow or outline drawn at another thickness.
    (tw, th), baseline = cv2.getTextSize(text, FONT, scale, thickness)
    rows, cols = np.nonzero(white)
    assert cols.min() + x0 >= org[0] - 1 and cols.max() + x0 <= org[0] + tw + 1
    assert rows.min() + y0 >= org[1] - th - 1 and rows.max() + y0 <= org[1] + baseline + 1


def test_caption_error_tells_a_legible_caption_from_a_garbled_one():
    frame = np.full((240, 320, 3), 150, np.uint8)
    text = LONG
    assert caption_error(caption(frame, text), text) == 0.0
    assert caption_error(caption(frame, text.upper()), text) > 25.0
    assert caption_error(frame, text) > 100.0


def test_video_captions_read_after_encoding(quick_run):
    config = load_config(quick_run)
    video = iio.imread(quick_run / "video.mp4")
    n_robot = len(ReplayFile.load(quick_run).recording.qpos)
    teacher = TEACHER_CAPTION.format(speedup=config.teacher_speedup)
    robot = ROBOT_CAPTION.format(weight=config.collision_weight)
    assert caption_error(video[0], teacher) < 20.0
    assert caption_error(video[-n_robot], robot) < 20.0


def test_video_shows_liquid_in_the_glass_while_pouring(quick_run):
    config = load_config(quick_run)
    video = iio.imread(quick_run / "video.mp4")
    states = ReplayFile.load(quick_run).recording.states()
    robot = video[len(video) - len(states["qpos"]) :]  # the video ends with the replay
    model = build_model(config.scene(teacher=True))
    data = mujoco.MjData(model)
    height, width = robot.shape[1:3]
    counts = []
    for frame, *state in zip(robot, *states.values(), strict=True):
        data.qpos[:], data.mocap_pos[:], data.mocap_quat[:] = state
        mujoco.mj_kinematics(model, data)
        mujoco.mj_camlight(model, data)
        if data.body(objects.BOTTLE).xmat[8] > 0.0:  # the bottle's axis points up: not pouring
            continue
        counts.append(np.count_nonzero(_liquid(frame) & _glass_region(model, data, width, height)))
    assert counts, "the replay never tilts the bottle past horizontal"
    assert max(counts) >= 10, counts


def test_frames_rendered_in_two_threads_are_those_of_one(quick_run):
    """Frame ``i`` depends on ``i`` alone: two threads, each with its own renderer, give the
    teacher's and the robot's frames bit for bit, in order (5 and 6 of them: an odd count ends
    in the first thread)."""
    config = load_config(quick_run)
    times = np.linspace(1.0, 6.0, 5)
    motion = script_demonstrations(config.teacher())
    states = ReplayFile.load(quick_run).recording.states()
    shown = np.linspace(0, len(states["qpos"]) - 1, 6).astype(int)
    states = {name: value[shown] for name, value in states.items()}
    for frames in (
        lambda threads: teacher_frames(motion, times, 96, 72, threads=threads),
        lambda threads: replay_frames(config.scene(), states, 96, 72, threads=threads),
    ):
        one, two = list(frames(1)), list(frames(2))
        assert len(one) == len(two) in (5, 6)
        assert np.array_equal(np.array(one), np.array(two))
        assert not np.array_equal(one[0], one[-1])  # the frames differ: their order counts


def test_quick_frames_look_like_the_full_ones(quick_run):
    """``quick`` (no multisampling, no reflections: the run's video) changes edges, not what a
    frame shows: the same frames to a few levels of 255 on average."""
    config = load_config(quick_run)
    states = ReplayFile.load(quick_run).recording.states()
    shown = np.linspace(0, len(states["qpos"]) - 1, 3).astype(int)
    states = {name: value[shown] for name, value in states.items()}
    motion = script_demonstrations(config.teacher())
    for frames in (
        lambda quick: teacher_frames(motion, np.array([2.0, 4.0]), 160, 120, quick=quick),
        lambda quick: replay_frames(config.scene(), states, 160, 120, quick=quick),
    ):
        full, quick = np.array(list(frames(False)), float), np.array(list(frames(True)), float)
        assert full.shape == quick.shape
        assert 0 < np.abs(full - quick).mean() < 4


def test_interleaved_threads_stop_with_their_caller_and_hand_on_an_error():
    def part(every: slice):
        yield from range(10)[every]

    items = interleaved(part, 3)
    assert [next(items) for _ in range(4)] == [0, 1, 2, 3]
    items.close()  # the caller stops early: every thread ends
    assert not [t for t in threading.enumerate() if t.name == "imitate-render"]
    assert list(interleaved(part, 3)) == list(range(10)) == list(interleaved(part, 1))

    def failing(every: slice):
        yield every.start
        if every.start == 1:
            raise ImitateError("no OpenGL context")
        yield every.start + 2

    with pytest.raises(ImitateError, match="no OpenGL context"):
        list(interleaved(failing, 2))
    assert not [t for t in threading.enumerate() if t.name == "imitate-render"]


def _liquid(frame: np.ndarray) -> np.ndarray:
    """Pixels ``(h, w) bool`` with the liquid's hue, saturated and not dark."""
    hsv = cv2.cvtColor(frame, cv2.COLOR_RGB2HSV).astype(int)
    rgb = np.uint8([[np.array(PARTICLE_RGBA[:3]) * 255]])
    hue = int(cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV)[0, 0, 0])
    gap = np.abs(hsv[..., 0] - hue)
    return (np.minimum(gap, 180 - gap) < 10) & (hsv[..., 1] > 120) & (hsv[..., 2] > 60)


def _glass_region(model, data, width: int, height: int) -> np.ndarray:
    """Pixels ``(h, w) bool`` of the glass and just above its rim, seen from the pour camera."""
    k, rotation, position = camera_parameters(model, data, scene_names.POUR_VIEW, width, height)
    glass = data.body(objects.GLASS)
    shape = objects.GLASS_SHAPE
    ring = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    local = [
        (r * np.cos(a), r * np.sin(a), z)
        for r, z in ((shape.profile[0][0], 0.0), (shape.profile[-1][0], shape.height + 0.03))
        for a in ring
    ]
    world = glass.xpos + np.array(local) @ glass.xmat.reshape(3, 3).T
    pix = (world - position) @ rotation.T @ k.T
    pix = pix[:, :2] / pix[:, 2:]
    hull = cv2.convexHull(np.round(pix).astype(np.int32))
    mask = np.zeros((height, width), np.uint8)
    cv2.fillConvexPoly(mask, hull, 1)
    return mask.astype(bool)


def test_the_teachers_pauses_play_faster_than_the_demonstrations():
    from imitate.stages.figures import _teacher_times

    times = _teacher_times(np.array([[1.0, 2.0], [3.0, 4.0]]), 5.0, 0.1, 0.5)
    steps = np.diff(times)
    moving = ((times[:-1] >= 1.0) & (times[:-1] < 2.0)) | ((times[:-1] >= 3.0) & (times[:-1] < 4.0))
    assert np.allclose(steps[moving], 0.1) and np.allclose(steps[~moving], 0.5)
    assert times[0] == 0.0 and times[-1] < 5.0 and moving.sum() == 20


def test_a_full_disk_is_named_not_hidden_by_ffmpegs_broken_pipe(tmp_path, monkeypatch):
    """Review N-c2: ffmpeg stops when the disk fills, and its broken pipe is all one sees."""
    import os

    from imitate.envs import video

    def frames():
        yield np.zeros((16, 16, 3), np.uint8)
        raise BrokenPipeError(32, "Broken pipe")  # as imageio's writer when ffmpeg has died

    full = os.statvfs_result((4096, 4096, 100, 0, 0, 100, 0, 0, 0, 255))
    monkeypatch.setattr(video.os, "statvfs", lambda folder: full)
    with pytest.raises(OSError, match=r"No space left on device.*v\.mp4") as error:
        video.write_video(tmp_path / "v.mp4", frames(), fps=10)
    assert error.value.errno == 28
    assert list(tmp_path.iterdir()) == []
    monkeypatch.undo()
    with pytest.raises(BrokenPipeError):  # space left: the error as it came
        video.write_video(tmp_path / "v.mp4", frames(), fps=10)
