"""The observation stage: the robot's cameras in the simulation, the tracker on the rendered
session against ground truth."""

import dataclasses
import threading

import cv2
import mujoco
import numpy as np
import pytest

from imitate.envs import observation
from imitate.envs.assembly import SceneConfig, build_model
from imitate.envs.teacher_motion import TeacherConfig
from imitate.errors import ImitateError
from imitate.perception import (
    ColourRange,
    ObjectModel,
    PerceptionConfig,
    StereoTracker,
    object_models,
    perception_config,
    track,
)
from imitate.perception.watch import cameras, ground_truth, watch


@pytest.fixture(scope="module")
def rendered_session():
    """Eight 320x240 stereo pairs spread over the first demonstration, with ground truth."""
    config = observation.ObservationConfig(
        teacher=TeacherConfig(n_demos=2, seed=3), width=320, height=240
    )
    sess = observation.session(config)
    start, end = sess.motion.boundaries[0]
    sess = dataclasses.replace(sess, times=np.linspace(start - 0.3, end + 0.3, 8))
    return sess, list(observation.frames(sess))


def test_tracking_rendered_frames_matches_ground_truth(rendered_session):
    sess, pairs = rendered_session
    timing = {}
    tracker = StereoTracker(*cameras(sess), perception_config(sess.motion.objects))
    tracks = track(tracker, pairs, sess.times, timing)
    truth = ground_truth(sess, tracks.objects)
    assert tracks.detected.all() and timing["track"] > 0
    error = np.linalg.norm(tracks.position - truth.position, axis=-1)
    assert np.median(error) < 0.008 and error.max() < 0.03  # [m], at 320x240
    turn = np.abs(np.angle(np.exp(1j * (tracks.angle - truth.angle))))
    assert np.degrees(np.median(turn)) < 2.0 and np.degrees(turn.max()) < 6.0


def test_tracking_runs_opencv_in_one_thread_and_restores_its_threads(rendered_session):
    sess, pairs = rendered_session
    threads = cv2.getNumThreads()
    seen = []

    def tracker():
        return StereoTracker(*cameras(sess), perception_config(sess.motion.objects))

    def counted():
        for pair in pairs:
            seen.append(cv2.getNumThreads())
            yield pair

    cv2.setNumThreads(2)  # OpenCV's own threads where the tracker used them before
    try:
        reference = tracker()
        expected = [reference.update(*pair) for pair in pairs]
        tracks = track(tracker(), counted(), sess.times)
        assert seen == [1] * len(pairs) and cv2.getNumThreads() == 2
        for k, obj in enumerate(tracks.objects):
            ends = np.array([m[obj].ends for m in expected])
            assert np.array_equal(tracks.position[k], ends.mean(axis=1))
        with pytest.raises(ImitateError):  # restored after an error too
            track(tracker(), pairs, sess.times[:2])
        assert cv2.getNumThreads() == 2
    finally:
        cv2.setNumThreads(threads)


def test_tracker_recovers_after_an_object_leaves_the_view(rendered_session):
    sess, pairs = rendered_session
    tracker = StereoTracker(*cameras(sess), perception_config(sess.motion.objects))
    blank = np.full_like(pairs[0][0], 200)
    assert all(m is not None for m in tracker.update(*pairs[0]).values())
    assert all(m is None for m in tracker.update(blank, blank).values())
    assert all(m is not None for m in tracker.update(*pairs[1]).values())


def test_an_object_found_in_no_frame_is_named_with_its_colour(rendered_session):
    sess, pairs = rendered_session
    models = object_models(sess.motion.objects)
    purple = ObjectModel(
        "purple_cup", ColourRange((140, 100, 30), (160, 255, 255)), models[1].profile
    )
    config = PerceptionConfig(objects=(models[0], purple))
    with pytest.raises(ImitateError, match=r"'purple_cup'.*h 140..160, s 100..255, v 30..255"):
        track(StereoTracker(*cameras(sess), config), pairs[:3], sess.times[:3])


@pytest.mark.parametrize(
    "frame",
    [
        np.zeros((240, 320), np.uint8),
        np.zeros((240, 320, 3), np.float32),
        np.zeros((480, 640, 3), np.uint8),
    ],
)
def test_frames_of_the_wrong_shape_or_dtype_are_refused(rendered_session, frame):
    sess, pairs = rendered_session
    tracker = StereoTracker(*cameras(sess), perception_config(sess.motion.objects))
    with pytest.raises(ImitateError, match=r"left frame not accepted: .*\(240, 320, 3\).*uint8"):
        tracker.update(frame, pairs[0][1])


def test_observe_tracks_the_whole_session_with_its_truth_and_timing():
    config = observation.ObservationConfig(
        teacher=TeacherConfig(n_demos=2, seed=1), width=160, height=120, fps=5
    )
    timing = {}
    observed = watch(config, timing=timing)
    tracks, truth = observed.tracks, observed.truth
    n = len(tracks.times)
    assert timing["pairs"] == n and timing["render"] > 0 and timing["track"] > 0
    assert tracks.position.shape == truth.position.shape == (2, n, 3)
    assert observed.projections.shape == (2, 3, 4) and observed.image_size == (160, 120)
    assert tracks.detected.mean() > 0.5  # 160x120: the glass is small
    assert np.nanmedian(np.linalg.norm(tracks.position - truth.position, axis=-1)) < 0.03


def test_an_unknown_camera_is_refused_with_the_cameras_named():
    model = build_model(SceneConfig(teacher=False))
    with pytest.raises(ImitateError, match=r"camera 'nose' not in the model; its cameras: \["):
        observation.camera_parameters(model, mujoco.MjData(model), "nose", 64, 48)


def test_pairs_rendered_ahead_are_those_rendered_here_in_order():
    config = observation.ObservationConfig(
        teacher=TeacherConfig(n_demos=2, seed=1), width=160, height=120, fps=5
    )
    sess = observation.session(config)
    sess = dataclasses.replace(sess, times=sess.times[: 2 * observation.RENDER_AHEAD + 3])
    here = list(observation.frames(sess, ahead=False))
    timing = {}
    ahead = list(observation.frames(sess, timing))
    assert len(ahead) == len(here) == len(sess.times)
    assert np.array_equal(np.array(here), np.array(ahead))
    assert timing["render"] > 0


def test_the_render_thread_stops_with_its_caller_and_hands_on_its_error(monkeypatch):
    config = observation.ObservationConfig(
        teacher=TeacherConfig(n_demos=2, seed=1), width=64, height=48, fps=10
    )
    sess = observation.session(config)
    pairs = observation.frames(sess)
    next(pairs)
    pairs.close()  # the caller stops early: the thread ends, its context closed
    assert not [t for t in threading.enumerate() if t.name == "imitate-render"]

    def no_context(_sess):
        raise ImitateError("no OpenGL context")

    monkeypatch.setattr(observation, "_eye_renderer", no_context)
    with pytest.raises(ImitateError, match="no OpenGL context"):
        next(observation.frames(sess))


def test_the_eyes_render_without_what_the_tracker_does_not_need(rendered_session):
    sess, pairs = rendered_session
    corner = pairs[0][0][0, 0]  # the sky: black, not the skybox's grey
    assert sess.fast_render and not corner.any()
