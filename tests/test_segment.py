"""Stillness segmentation on synthetic tracks with known boundaries."""

import numpy as np
import pytest

from imitate.demos.segment import StillnessConfig, segment
from imitate.envs.observation import tracked_point
from imitate.envs.teacher_motion import TeacherConfig, script_demonstrations
from imitate.errors import ImitateError
from imitate.perception import Tracks
from imitate.taskspace import image_angle

# Gaze frame of a camera looking along +x, level: columns right, down, forward.
GAZE = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def _tracks(seed: int, noise: float, n_demos: int = 5):
    """Tracks of a scripted session at 30 Hz, with white noise of ``noise`` [m] per axis."""
    motion = script_demonstrations(TeacherConfig(n_demos=n_demos, seed=seed))
    times = np.arange(0.0, motion.duration, 1 / 30)
    poses = motion.poses(times)
    names = ("bottle", "glass")
    points, axes = (
        np.array(v) for v in zip(*(tracked_point(n, *poses[n]) for n in names), strict=True)
    )
    rng = np.random.default_rng(seed)
    angle = np.unwrap(image_angle(axes, GAZE), axis=-1)
    tracks = Tracks(
        times=times,
        objects=names,
        position=points + rng.normal(0.0, noise, points.shape),
        axis=axes,
        angle=angle + rng.normal(0.0, noise / 0.2, angle.shape),  # as if 0.2 m lever
        detected=np.ones(angle.shape, dtype=bool),
        gaze=GAZE,
        gaps=(),
    )
    return tracks, motion.boundaries


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("noise", [0.0, 0.0015])
def test_every_demonstration_is_found_near_its_true_boundaries(seed, noise):
    tracks, truth = _tracks(seed, noise)
    demos = segment(tracks)
    found = np.array([(d.start, d.end) for d in demos])
    assert found.shape == truth.shape
    assert np.abs(found - truth).max() < 0.15


def test_demonstrations_hold_only_their_frames():
    tracks, _ = _tracks(0, 0.0, n_demos=3)
    for demo in segment(tracks):
        assert demo.times[0] >= demo.start and demo.times[-1] <= demo.end
        assert demo.position.shape == (2, len(demo.times), 3) and demo.angle.shape == (
            2,
            len(demo.times),
        )


def test_one_demonstration_is_not_enough_and_the_settings_are_named():
    tracks, _ = _tracks(0, 0.0, n_demos=1)
    with pytest.raises(ImitateError, match=r"found 1 demonstration.*min_still=0.5 s, still_range"):
        segment(tracks)


def test_settings_that_see_no_stillness_find_nothing():
    tracks, _ = _tracks(1, 0.0015, n_demos=3)
    with pytest.raises(ImitateError, match="found 0 demonstration"):
        segment(tracks, StillnessConfig(still_range=1e-4))


def test_demos_round_trip(tmp_path):
    tracks, _ = _tracks(2, 0.0, n_demos=2)
    demos = segment(tracks)
    from imitate.stages.files import DemosFile

    DemosFile(tuple(demos), tracks.objects, tracks.gaze).save(tmp_path)
    loaded = DemosFile.load(tmp_path)
    assert loaded.objects == tracks.objects and np.array_equal(loaded.gaze, GAZE)
    for a, b in zip(demos, loaded.segments, strict=True):
        assert (a.start, a.end) == (b.start, b.end)
        assert np.array_equal(a.position, b.position) and np.array_equal(a.angle, b.angle)


def test_bad_settings_are_refused():
    with pytest.raises(ImitateError, match="min_still"):
        StillnessConfig(min_still=0.0)
