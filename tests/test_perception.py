"""Stereo perception: camera model against MuJoCo's renderer, rim correction, gaps, artifact."""

import mujoco
import numpy as np
import pytest

from imitate.envs.assembly import SceneConfig, build_spec
from imitate.envs.observation import EYES, camera_parameters
from imitate.envs.rendering import make_renderer
from imitate.errors import ImitateError
from imitate.perception import (
    ColourRange,
    GroundTruth,
    Observations,
    PinholeCamera,
    StereoTracker,
    fill_gaps,
    perception_config,
    tracks_from_ends,
    triangulate,
)
from imitate.perception._rim import _correct_ends
from imitate.taskspace import gaze_of_camera, image_angle

POURING = ("bottle", "glass")  # the objects tracked
RED = ColourRange((170, 120, 40), (8, 255, 255))  # wraps around hue 0
MARKERS = np.array([[0.62, 0.05, 1.10], [0.70, -0.12, 1.02], [0.55, 0.10, 0.98]])  # [m]


@pytest.fixture(scope="module")
def marker_views():
    """Left and right 640x480 images of red spheres at MARKERS, with the cameras."""
    spec = build_spec(SceneConfig(teacher=False))
    for i, pos in enumerate(MARKERS):
        body = spec.worldbody.add_body(name=f"marker_{i}", pos=pos)
        body.add_geom(
            name=f"marker_{i}",
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=(0.01, 0, 0),
            rgba=(0.9, 0.05, 0.05, 1),
            contype=0,
            conaffinity=0,
        )
    model = spec.compile()
    data = mujoco.MjData(model)
    data.qpos[model.joint("head_tilt").qposadr[0]] = 0.3
    mujoco.mj_forward(model, data)
    renderer = make_renderer(model, 480, 640)
    images, cameras = [], []
    for eye in EYES:
        renderer.update_scene(data, camera=eye)
        images.append(renderer.render())
        cameras.append(PinholeCamera(*camera_parameters(model, data, eye, 640, 480), 640, 480))
    renderer.close()
    return images, cameras


def _marker_centroids(image):
    import cv2

    mask = RED.mask(cv2.cvtColor(image, cv2.COLOR_RGB2HSV))
    count, _, _, centroids = cv2.connectedComponentsWithStats(mask)
    return centroids[1:]


def test_projection_matches_the_rendered_images(marker_views):
    images, cameras = marker_views
    for image, camera in zip(images, cameras, strict=True):
        seen = _marker_centroids(image)
        predicted = camera.project(MARKERS)
        assert len(seen) == len(MARKERS)
        nearest = np.linalg.norm(seen[:, None] - predicted[None], axis=-1).min(axis=0)
        assert nearest.max() < 0.25  # [px]; a half-pixel convention error would fail


def test_triangulation_of_rendered_markers_is_sub_millimetre(marker_views):
    images, (left, right) = marker_views
    seen_left, seen_right = (_marker_centroids(image) for image in images)
    # Match by the nearest predicted projection, then triangulate what was seen.
    order_left = np.argmin(
        np.linalg.norm(seen_left[:, None] - left.project(MARKERS)[None], axis=-1), axis=0
    )
    order_right = np.argmin(
        np.linalg.norm(seen_right[:, None] - right.project(MARKERS)[None], axis=-1), axis=0
    )
    points = triangulate(left, right, seen_left[order_left], seen_right[order_right])
    assert np.linalg.norm(points - MARKERS, axis=1).max() < 1e-3


def test_triangulation_inverts_projection(marker_views):
    _, (left, right) = marker_views
    points = np.random.default_rng(0).uniform([0.5, -0.4, 0.7], [1.5, 0.4, 1.4], (50, 3))
    back = triangulate(left, right, left.project(points), right.project(points))
    assert np.abs(back - points).max() < 1e-9


@pytest.mark.parametrize("tilt", [90.0, -10.0])  # degrees from lying across the view
def test_rim_correction_recovers_the_ends_from_exact_extremes(marker_views, tilt):
    """The compiled rim correction (module step 5) on exact synthetic rim extremes of the
    bottle, upright and lying across the view tilted away from the eyes."""
    _, cameras = marker_views
    tracker = StereoTracker(*cameras, perception_config(POURING))
    bottle = tracker.config.objects[0]
    radii = bottle.radius(np.array([0.0, bottle.height]))
    eyes = 0.5 * (cameras[0].position + cameras[1].position)
    middle = np.array([0.62, 0.0, 1.05])  # [m]
    sight = (middle - eyes) / np.linalg.norm(middle - eyes)
    across = np.cross(sight, [0.0, 0.0, 1.0])
    across /= np.linalg.norm(across)
    towards = np.cross(across, sight) if tilt == 90.0 else sight  # up, or along the sight
    axis = np.cos(np.radians(tilt)) * across + np.sin(np.radians(tilt)) * towards
    ends = middle + np.outer([-0.5, 0.5], axis * bottle.height)
    u = np.cross(axis, sight)
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    phases = np.linspace(0.0, 2 * np.pi, 3600, endpoint=False)[:, None]
    circle = np.cos(phases) * u + np.sin(phases) * v
    origins, directions, extents = [], [], []
    for cam in cameras:
        centres = cam.project(ends)
        direction = (centres[1] - centres[0]) / np.linalg.norm(centres[1] - centres[0])
        along = [
            (cam.project(ends[j] + radii[j] * circle) - centres[0]) @ direction for j in (0, 1)
        ]
        origins.append(centres[0])
        directions.append(direction)
        extents.append([along[0].min(), along[1].max()])
    origins, directions, extents = map(np.array, (origins, directions, extents))
    extremes = origins[:, None] + extents[:, :, None] * directions[:, None]
    raw = triangulate(*cameras, extremes[0], extremes[1])
    corrected = _correct_ends(
        raw, eyes, radii, *tracker._camera_arrays, origins, directions, extents, 4
    )
    assert np.abs(raw - ends).max() > 0.005  # the extremes are not the rim centres
    assert np.abs(corrected - ends).max() < 1e-3


def test_gaze_of_the_left_camera_is_right_handed(marker_views):
    _, (left, _) = marker_views
    gaze = gaze_of_camera(left.rotation)
    assert np.allclose(gaze.T @ gaze, np.eye(3)) and np.linalg.det(gaze) > 0
    assert gaze[:, 2] @ np.array([1.0, 0.0, 0.0]) > 0.9  # looks at the teacher (+x)
    upright = np.array([0.0, 0.0, 1.0])
    assert image_angle(upright, gaze) == pytest.approx(-np.pi / 2, abs=0.01)


def test_short_gaps_are_interpolated_and_long_ones_reported():
    times = np.arange(20) / 10.0
    values = np.stack([times, 2 * times], axis=1)
    valid = np.ones(20, dtype=bool)
    valid[[0, 1]] = False  # at the start: nothing before it
    valid[5:7] = False  # 0.3 s between valid samples: short
    valid[10:16] = False  # 0.7 s: long
    filled, gaps = fill_gaps(times, values, valid, max_gap=0.35)
    assert gaps == [(0, 2, False), (5, 7, True), (10, 16, False)]
    assert np.allclose(filled[5:7], values[5:7])
    assert np.isnan(filled[[0, 1, 10, 15]]).all() and np.isfinite(filled[[4, 7, 9, 16]]).all()


def _tracks_with_gaps():
    """Two upright objects moving along x at 30 Hz; the bottle's gap is short, the glass's long."""
    perception = perception_config(POURING, max_gap=0.1)
    times = np.arange(30) / 30.0
    ends = np.zeros((2, 30, 2, 3))
    ends[:, :, 1, 2] = 0.2  # upright, 0.2 m long
    ends[:, :, :, 0] = times[:, None]  # moving along x
    ends[0, 10:12] = np.nan  # 3/30 s between valid samples: interpolated
    ends[1, 20:27] = np.nan  # too long
    return tracks_from_ends(times, perception.objects, ends, np.eye(3), perception)


def test_tracks_report_long_gaps_and_fill_short_ones():
    tracks = _tracks_with_gaps()
    times = tracks.times
    assert [(g.obj, g.interpolated) for g in tracks.gaps] == [("bottle", True), ("glass", False)]
    assert tracks.long_gaps[0].start == pytest.approx(20 / 30) and tracks.long_gaps[
        0
    ].end == pytest.approx(26 / 30)
    assert np.allclose(tracks.position[0, 10:12, 0], times[10:12])
    assert np.isnan(tracks.position[1, 20:27]).all()


def test_observations_round_trip(tmp_path):
    from imitate.stages.files import ObservationsFile

    tracks = _tracks_with_gaps()
    truth = GroundTruth(tracks.position, tracks.axis, tracks.angle, np.array([[0.1, 0.9]]))
    saved = Observations(tracks, np.arange(24.0).reshape(2, 3, 4), (320, 240), truth)
    ObservationsFile(saved).save(tmp_path)
    loaded = ObservationsFile.load(tmp_path).observations
    assert loaded.tracks.objects == tracks.objects and loaded.tracks.gaps == tracks.gaps
    for name in ("times", "position", "axis", "angle", "detected", "gaze"):
        assert np.array_equal(getattr(loaded.tracks, name), getattr(tracks, name), equal_nan=True)
    assert np.array_equal(loaded.projections, saved.projections)
    assert loaded.image_size == (320, 240)
    for name in ("position", "axis", "angle", "boundaries"):
        assert np.array_equal(getattr(loaded.truth, name), getattr(truth, name), equal_nan=True)


@pytest.mark.parametrize(
    "lower, upper",
    [((0, 0, 0), (180, 255, 255)), ((0, 200, 0), (10, 100, 255)), ((0, 0), (1, 1, 1))],
)
def test_bad_colour_ranges_are_refused(lower, upper):
    with pytest.raises(ImitateError, match="colour range"):
        ColourRange(lower, upper)
