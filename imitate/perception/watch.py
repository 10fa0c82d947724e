"""The robot watches the teacher's session and tracks the objects (the ``observe`` stage's body).

The simulation (:mod:`imitate.envs.observation`) renders the session from the robot's head
cameras; the stereo tracker (:mod:`imitate.perception`) runs on every pair, with cameras built
from the simulated cameras' parameters; the ground truth is kept beside the tracks for
evaluation.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np

from imitate.envs.observation import ObservationConfig, Session, frames, session, tracked_point
from imitate.perception import (
    GroundTruth,
    Observations,
    PerceptionConfig,
    PinholeCamera,
    StereoTracker,
    perception_config,
    track,
)
from imitate.taskspace import gaze_of_camera, image_angle


def cameras(sess: Session) -> tuple[PinholeCamera, PinholeCamera]:
    """The left and right cameras of ``sess`` as the tracker's pinhole models."""
    left, right = (PinholeCamera(*params, sess.width, sess.height) for params in sess.cameras)
    return left, right


def ground_truth(sess: Session, names: tuple[str, ...]) -> GroundTruth:
    """True tracked points, axes and angles of ``names`` (held objects and places) at the
    session's frame times."""
    poses = {**sess.motion.poses(sess.times), **sess.motion.place_poses(sess.times)}
    gaze = gaze_of_camera(cameras(sess)[0].rotation)
    points, axes = zip(*(tracked_point(name, *poses[name]) for name in names), strict=True)
    axis = np.array(axes)
    return GroundTruth(
        position=np.array(points),
        axis=axis,
        angle=np.unwrap(image_angle(axis, gaze), axis=-1),
        boundaries=sess.motion.boundaries.copy(),
    )


def watch(
    config: ObservationConfig,
    perception: PerceptionConfig | None = None,
    timing: dict | None = None,
    progress: bool | Callable[..., Iterable] = False,
) -> Observations:
    """Render the teacher's session from the robot's eyes and track the objects.

    Args:
        config: session and cameras.
        perception: tracker settings; by default :func:`imitate.perception.perception_config`
            of what the session's teacher shows (its task's tool, target and places).
        timing: if given, receives ``"render"`` and ``"track"`` (tracking and triangulation)
            totals [s] and ``"pairs"``.
        progress: show a progress bar (tqdm's); or tqdm's stand-in that wraps the pairs,
            called as tqdm is.

    Returns:
        Tracks, camera matrices and ground truth.
    """
    sess = session(config)
    perception = perception or perception_config(sess.motion.watched)
    left, right = cameras(sess)
    timing = {} if timing is None else timing
    pairs: Iterable = frames(sess, timing)
    if progress:
        if progress is True:
            from tqdm import tqdm

            progress = tqdm
        assert callable(progress)
        pairs = progress(pairs, total=len(sess.times), desc="observe", unit="pair")
    tracks = track(StereoTracker(left, right, perception), pairs, sess.times, timing)
    timing["pairs"] = len(sess.times)
    return Observations(
        tracks=tracks,
        projections=np.array([cam.projection for cam in (left, right)]),
        image_size=(config.width, config.height),
        truth=ground_truth(sess, tracks.objects),
    )
