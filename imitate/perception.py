r"""Stereo colour tracking of the bottle and glass from the robot's head cameras (paper II).

Per object and per image of a stereo pair:

1. **Segmentation**: HSV thresholds (:class:`ColourRange`) inside a window around the object's
   last detection (a coarse search of the whole image to acquire or re-acquire it), a
   morphological opening, and the connected components that are not specks.
2. **Moments**: centroid and principal axis; the axis's sign (bottom to top) is carried from
   frame to frame, starting from "top up in the image".
3. **Occlusion-aware axis line**: the teacher's hands cover part of an object, often a whole
   side of the glass, which drags the centroid and the principal axis. The silhouette is cut
   into slices across its axis; each slice's edge that borders the background (not an occluder
   colour, not near the ends) lies one apparent radius from the axis, the radius being known
   from the object's profile (:class:`ObjectModel`) and its depth. A least-squares line through
   these gives the image of the object's axis.
4. **Extremes** of the silhouette along that line, the images of the bottom and top rims:
   sub-pixel, the mean of the outline within a pixel of each extreme.

Then per object, from the two views (cameras from MuJoCo's parameters, :func:`mujoco_camera`):

5. **Ends**: the extremes are triangulated, then corrected: a rim's extreme point is not its
   centre (for a bottle lying across the view the extremes are the rims' nearest points, 2-4 cm
   in front of the axis). With the current 3D estimate the model predicts, per view, how far the
   extreme lies beyond the projected rim centre; shifting the observed extremes back by that and
   re-triangulating converges in a few iterations. While the axis lies across the view (near
   the epipolar plane, so the two axis lines do not fix its tilt in depth) the correction has
   two self-consistent results, the axis tilted towards or away from the eyes; it is run from
   the triangulated extremes and from those with the axis mirrored in the plane normal to the
   line of sight, and the result that better fits both views' extremes and axis lines is kept.
6. **Tracked point**: the middle of the two rim centres, i.e. the centre of the object's axis at
   half its height (bottle 0.1175 m, glass 0.05 m above the bottom), which is what the ground
   truth uses. **Axis**: the unit vector bottom to top. **Angle** around the gaze vector:
   ``atan2(a . g_1, a . g_0)`` in the gaze frame ``g`` (:func:`gaze_frame`).

Why not simply triangulate the blob centroids: the silhouette's centroid sits below half height
(the bottle's wide body weighs more than its neck: -12 mm along the axis), and a hand in front
of an object shifts the centroid differently in the two views, which shows up as depth error
(-6 mm for the bottle, -18 mm for the glass over a recorded session); steps 3-5 remove both.

Limits: when an object's axis lies across the view (the bottle while it pours), its depth rests
on the two ends alone; a tenth of a pixel of disparity is 2 mm of depth at 1.1 m, so the bottle's
tracked point is then a few mm to 3 cm off in depth (largest where the teacher's forearm borders
an end in one view), against 2-3 mm when it is upright. The two results of step 5 can also
both fit the views exactly: on exact synthetic extremes, a bottle lying across the view tilted
about 20 degrees towards the eyes converges to a wrong tilt from both starts (6 cm off at the
ends).

Speed: the loops over the outline in steps 3-4 and the correction of step 5 are compiled
(numba; compiled on a process's first call or loaded from numba's on-disk cache), where NumPy's
per-call overhead on these small arrays had been most of the time; the rest is OpenCV.

Frames in which an object is not found are gaps; :func:`fill_gaps` interpolates short ones and
reports long ones.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import cv2
import mujoco
import numba
import numpy as np

from imitate.artifacts import load_npz, save_npz
from imitate.errors import ImitateError


@dataclass(frozen=True)
class PinholeCamera:
    """A calibrated camera in OpenCV's convention (x right, y down, z forward).

    Attributes:
        intrinsics: ``K`` ``(3, 3)`` [px]; pixel ``(col, row)`` of a pixel's centre is its index.
        rotation: ``(3, 3)`` world-to-camera rotation (rows: the camera axes in world coordinates).
        position: ``(3,)`` optical centre in the world frame [m].
        width: image width [px].
        height: image height [px].
    """

    intrinsics: np.ndarray
    rotation: np.ndarray
    position: np.ndarray
    width: int
    height: int

    @property
    def projection(self) -> np.ndarray:
        """``P = K [R | -R c]``, ``(3, 4)``."""
        return self.intrinsics @ np.hstack(
            [self.rotation, -(self.rotation @ self.position)[:, None]]
        )

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates ``(..., 2)`` of world points ``(..., 3)`` [m]."""
        cam = (np.asarray(points, dtype=float) - self.position) @ self.rotation.T
        pix = cam @ self.intrinsics.T
        return pix[..., :2] / pix[..., 2:]

    def directions(self, pixels: np.ndarray) -> np.ndarray:
        """Viewing directions ``(..., 3)`` (unit depth, not unit length) through ``pixels``.

        Args:
            pixels: ``(..., 2)`` ``(col, row)`` [px].

        Returns:
            World-frame vectors whose component along the optical axis is 1.
        """
        k = self.intrinsics
        pixels = np.asarray(pixels, dtype=float)
        x = (pixels[..., 0] - k[0, 2]) / k[0, 0]
        y = (pixels[..., 1] - k[1, 2]) / k[1, 1]
        r = self.rotation
        return x[..., None] * r[0] + y[..., None] * r[1] + r[2]


def mujoco_camera(model, data, camera: str, width: int, height: int) -> PinholeCamera:
    """The pinhole model of MuJoCo camera ``camera`` rendering ``width x height`` images.

    Uses the camera's pose in ``data`` (after kinematics) and its vertical field of view
    ``cam_fovy``; MuJoCo's pixels are square and its optical axis passes through the image
    centre, between the two middle pixels.

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
    return PinholeCamera(intrinsics, rotation, data.cam_xpos[cam_id].copy(), width, height)


def triangulate(left: PinholeCamera, right: PinholeCamera, pl: np.ndarray, pr: np.ndarray):
    """Triangulation of corresponding pixels: the midpoint of the rays' closest approach.

    Args:
        left: first camera.
        right: second camera.
        pl: ``(..., 2)`` pixels in the first camera's image.
        pr: ``(..., 2)`` the corresponding pixels in the second camera's image.

    Returns:
        ``(..., 3)`` world points [m]; exact for exactly corresponding pixels.
    """
    d1, d2 = left.directions(pl), right.directions(pr)
    w0 = left.position - right.position
    a, b, c = (d1 * d1).sum(-1), (d1 * d2).sum(-1), (d2 * d2).sum(-1)
    d, e = d1 @ w0, d2 @ w0
    denom = a * c - b * b  # > 0 unless the rays are parallel (a point at infinity)
    t1, t2 = (b * e - c * d) / denom, (a * e - b * d) / denom
    return 0.5 * (left.position + t1[..., None] * d1 + right.position + t2[..., None] * d2)


@dataclass(frozen=True)
class ColourRange:
    """An HSV box in OpenCV's 8-bit units: hue 0..179 (half degrees), saturation and value 0..255.

    A hue range with ``lower[0] > upper[0]`` wraps around red (e.g. 170..10).

    Attributes:
        lower: ``(h, s, v)`` inclusive lower bounds.
        upper: ``(h, s, v)`` inclusive upper bounds.
    """

    lower: tuple[int, int, int]
    upper: tuple[int, int, int]

    def __post_init__(self):
        limits = (179, 255, 255)
        for name in ("lower", "upper"):
            value = getattr(self, name)
            if len(value) != 3 or not all(
                isinstance(v, int | np.integer) and 0 <= v <= top
                for v, top in zip(value, limits, strict=True)
            ):
                raise ImitateError(
                    f"colour range {name}={value!r} not accepted: three integers (h, s, v) with "
                    f"h in 0..179, s and v in 0..255 (OpenCV's 8-bit HSV)"
                )
        if self.lower[1] > self.upper[1] or self.lower[2] > self.upper[2]:
            raise ImitateError(
                f"colour range {self.lower}..{self.upper} not accepted: saturation and value need "
                f"lower <= upper (only hue may wrap around)"
            )

    def mask(self, hsv: np.ndarray) -> np.ndarray:
        """``uint8`` mask (255 inside) of an HSV image ``(h, w, 3)``."""
        lo, hi = np.array(self.lower, np.uint8), np.array(self.upper, np.uint8)
        if lo[0] <= hi[0]:
            return cv2.inRange(hsv, lo, hi)
        top, bottom = hi.copy(), lo.copy()
        top[0], bottom[0] = 179, 0
        return cv2.inRange(hsv, lo, top) | cv2.inRange(hsv, bottom, hi)


# Skin, the colour of the teacher's hands: what may cover an object's side.
SKIN = ColourRange((0, 40, 60), (25, 170, 255))


@dataclass(frozen=True)
class ObjectModel:
    """What the robot knows about an object: its colour and its shape.

    Attributes:
        name: the object's name.
        colour: its colour range.
        profile: ``(n, 2)`` points ``(radius, height)`` of its outer surface of revolution,
            bottom (height 0) to top, heights increasing [m].
    """

    name: str
    colour: ColourRange
    profile: tuple[tuple[float, float], ...]

    def __post_init__(self):
        prof = np.asarray(self.profile, dtype=float)
        if (
            prof.ndim != 2
            or prof.shape[0] < 2
            or prof.shape[1] != 2
            or prof[0, 1] != 0
            or np.any(np.diff(prof[:, 1]) <= 0)
            or np.any(prof[:, 0] <= 0)
        ):
            raise ImitateError(
                f"profile of {self.name!r} not accepted: at least two (radius, height) points "
                f"[m], radius > 0, heights increasing from 0; got {self.profile!r}"
            )

    @property
    def height(self) -> float:
        """Height of the object along its axis [m]."""
        return float(self.profile[-1][1])

    def radius(self, height: np.ndarray) -> np.ndarray:
        """Outer radius [m] at ``height`` [m] above the bottom (clamped to the profile)."""
        prof = np.asarray(self.profile, dtype=float)
        return np.interp(height, prof[:, 1], prof[:, 0])


@dataclass(frozen=True)
class PerceptionConfig:
    """Settings of the stereo tracker; sizes in pixels are for the image size tracked.

    Attributes:
        objects: the tracked objects.
        occluder: colour of what may cover an object's side (the teacher's skin); ``None``
            treats every edge as the object's own.
        min_area: smallest silhouette accepted [px].
        open_size: side of the opening's elliptic kernel [px]; 0 or 1 disables it.
        keep_fraction: connected components smaller than this fraction of the largest are
            dropped as specks; larger ones stay, so an object cut in two by a hand stays whole.
        window_margin: the search window is the last bounding box grown by this fraction of
            its size on every side (and at least ``min_margin``).
        min_margin: least growth of the search window [px].
        coarse_step: subsampling of the whole-image search that (re)acquires an object.
        end_zone: fraction of the silhouette's length at either end whose edges are not used
            for the axis line (rims and bottoms are not sides).
        min_edges: fewest free side edges for the occlusion-aware axis line; with fewer the
            moments' axis is kept.
        refine_iterations: iterations of the rim-extreme correction of the ends.
        max_gap: longest gap in a track that is interpolated [s]; longer ones are reported.
    """

    objects: tuple[ObjectModel, ...]
    occluder: ColourRange | None = SKIN
    min_area: int = 20
    open_size: int = 3
    keep_fraction: float = 0.1
    window_margin: float = 0.25
    min_margin: int = 12
    coarse_step: int = 4
    end_zone: float = 0.12
    min_edges: int = 6
    refine_iterations: int = 2
    max_gap: float = 0.25

    def __post_init__(self):
        names = [obj.name for obj in self.objects]
        if not names or len(set(names)) != len(names):
            raise ImitateError(f"objects {names} not accepted: one or more, with distinct names")
        for name in ("min_area", "coarse_step", "min_edges"):
            if not getattr(self, name) >= 1:
                raise ImitateError(f"{name}={getattr(self, name)!r} not accepted: an integer >= 1")
        if not 0 <= self.keep_fraction <= 1 or not 0 <= self.end_zone < 0.5:
            raise ImitateError(
                f"keep_fraction={self.keep_fraction!r}, end_zone={self.end_zone!r} not accepted: "
                f"keep_fraction in [0, 1], end_zone in [0, 0.5)"
            )
        if not self.max_gap >= 0 or not self.window_margin >= 0:
            raise ImitateError(
                f"max_gap={self.max_gap!r} s, window_margin={self.window_margin!r} not accepted: "
                f">= 0"
            )


def gaze_frame(camera: PinholeCamera) -> np.ndarray:
    """The gaze frame ``(3, 3)`` of ``camera``: columns right, ``forward x right``, forward.

    The middle column points down the image (OpenCV's y). The frame is right-handed, as
    ``imitate.taskspace`` requires, and its columns are the camera's axes in world coordinates.
    """
    return camera.rotation.T.copy()


def axis_angle(axis: np.ndarray, gaze: np.ndarray) -> np.ndarray:
    """Angle [rad] of ``axis (..., 3)`` around the gaze vector: ``atan2(a . g_1, a . g_0)``.

    An upright object seen by a level camera has angle ``-pi/2``; tilting its top towards the
    image's right brings the angle towards 0.
    """
    comp = np.asarray(axis, dtype=float) @ np.asarray(gaze, dtype=float)
    return np.arctan2(comp[..., 1], comp[..., 0])


@dataclass(frozen=True)
class ViewMeasurement:
    """One object in one image.

    Attributes:
        area: silhouette pixels.
        centroid: ``(2,)`` silhouette centroid ``(col, row)`` [px].
        origin: ``(2,)`` a point of the axis line [px].
        direction: ``(2,)`` unit direction of the axis line, bottom to top.
        extent: ``(2,)`` the silhouette's extremes along the line from ``origin`` [px].
        box: ``(col0, row0, col1, row1)`` bounding box, end exclusive [px].
        free_edges: side edges the axis line was fitted to (0: the moments' axis was kept).
    """

    area: int
    centroid: np.ndarray
    origin: np.ndarray
    direction: np.ndarray
    extent: np.ndarray
    box: tuple[int, int, int, int]
    free_edges: int

    @property
    def ends(self) -> np.ndarray:
        """``(2, 2)`` pixels of the extremes (bottom, top)."""
        return self.origin + np.outer(self.extent, self.direction)


@dataclass(frozen=True)
class Measurement:
    """One object in one stereo pair.

    Attributes:
        position: ``(3,)`` tracked point, the axis centre at half height, world frame [m].
        axis: ``(3,)`` unit long axis, bottom to top, world frame.
        ends: ``(2, 3)`` bottom and top centre, world frame [m].
        views: the left and right image measurements.
    """

    position: np.ndarray
    axis: np.ndarray
    ends: np.ndarray
    views: tuple[ViewMeasurement, ViewMeasurement]


def check_frame(frame: np.ndarray, camera: PinholeCamera, which: str) -> np.ndarray:
    """Raise ``ImitateError`` unless ``frame`` is a ``(height, width, 3)`` uint8 RGB image."""
    shape = (camera.height, camera.width, 3)
    if not isinstance(frame, np.ndarray) or frame.shape != shape or frame.dtype != np.uint8:
        got = (
            f"shape {frame.shape} dtype {frame.dtype}"
            if isinstance(frame, np.ndarray)
            else type(frame).__name__
        )
        raise ImitateError(
            f"{which} frame not accepted: an RGB image of shape {shape} and dtype uint8 (the "
            f"camera's size), got {got}"
        )
    return frame


class _Silhouette(NamedTuple):
    """An object's cleaned-up silhouette in a search window of one image."""

    hsv: np.ndarray  # (h, w, 3) the window in HSV
    offset: tuple[int, int]  # (col0, row0) of the window in the image
    mask: np.ndarray  # (h, w) uint8, 255 on the silhouette
    area: int  # [px]
    box: tuple[int, int, int, int]  # (col0, row0, col1, row1) in the image, end exclusive


class StereoTracker:
    """Tracks :attr:`PerceptionConfig.objects` through a sequence of stereo pairs.

    Args:
        left: the left camera (its frame is the gaze frame).
        right: the right camera; same image size as ``left``.
        config: tracker settings.
    """

    def __init__(self, left: PinholeCamera, right: PinholeCamera, config: PerceptionConfig):
        if (left.width, left.height) != (right.width, right.height):
            raise ImitateError(
                f"stereo cameras must render the same size; got {left.width}x{left.height} and "
                f"{right.width}x{right.height}"
            )
        self.cameras = (left, right)
        self._eyes = 0.5 * (left.position + right.position)  # between the optical centres [m]
        # (intrinsics (2, 3, 3) [px], rotations (2, 3, 3), positions (2, 3) [m]), for
        # the compiled rim correction.
        self._camera_arrays = tuple(
            np.ascontiguousarray([getattr(cam, name) for cam in self.cameras], dtype=float)
            for name in ("intrinsics", "rotation", "position")
        )
        self.config = config
        self._boxes: dict[tuple[str, int], tuple[int, int, int, int]] = {}
        self._directions: dict[tuple[str, int], np.ndarray] = {}
        self._profiles = {  # name: (heights (m,), radii (m,)) [m], for the compiled axis fit
            obj.name: tuple(
                np.ascontiguousarray(np.asarray(obj.profile, float)[:, i]) for i in (1, 0)
            )
            for obj in config.objects
        }

    def update(self, left: np.ndarray, right: np.ndarray) -> dict[str, Measurement | None]:
        """Measure every object in one stereo pair of RGB ``(height, width, 3)`` uint8 images.

        Returns:
            ``{object name: Measurement}``, ``None`` for an object not found in both images.

        Raises:
            ImitateError: a frame of the wrong shape or dtype.
        """
        frames = (
            check_frame(left, self.cameras[0], "left"),
            check_frame(right, self.cameras[1], "right"),
        )
        result = {}
        for obj in self.config.objects:
            found = [self._find(obj, view, frame) for view, frame in enumerate(frames)]
            result[obj.name] = None if None in found else self._measure(obj, found)
        return result

    # -- one view ---------------------------------------------------------------------------

    def _find(self, obj: ObjectModel, view: int, frame: np.ndarray) -> _Silhouette | None:
        """``obj``'s silhouette in one image, or ``None`` when it is not there.

        Searches the window kept from the last frame; where the silhouette reaches the window's
        border the window grows, where nothing is found the whole image is searched again.
        """
        cfg, key = self.config, (obj.name, view)
        height, width = frame.shape[:2]
        tracking = key in self._boxes
        window = self._boxes.pop(key) if tracking else self._acquire(obj, frame)
        while window is not None:
            c0, r0, c1, r1 = window
            hsv = cv2.cvtColor(np.ascontiguousarray(frame[r0:r1, c0:c1]), cv2.COLOR_RGB2HSV)
            found = self._silhouette(obj.colour.mask(hsv), hsv, (c0, r0))
            if found is None:
                window, tracking = (self._acquire(obj, frame) if tracking else None), False
                continue
            box = found.box
            grown = _grow(box, cfg.window_margin, cfg.min_margin, width, height)
            cut = (box[0] == c0 > 0, box[1] == r0 > 0, box[2] == c1 < width, box[3] == r1 < height)
            if any(cut):  # the silhouette may go on beyond the window: search a larger one
                window = _union(window, grown)
                continue
            self._boxes[key] = grown
            return found
        return None

    def _acquire(self, obj: ObjectModel, frame: np.ndarray):
        """Window around the largest ``obj``-coloured region of the whole image, or ``None``."""
        cfg, step = self.config, self.config.coarse_step
        small = np.ascontiguousarray(frame[::step, ::step])
        mask = obj.colour.mask(cv2.cvtColor(small, cv2.COLOR_RGB2HSV))
        count, _, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        if count < 2:
            return None
        best = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        x, y, w, h = stats[best, :4]
        box = (x * step, y * step, (x + w) * step, (y + h) * step)
        return _grow(box, cfg.window_margin, cfg.min_margin + step, frame.shape[1], frame.shape[0])

    def _silhouette(self, mask: np.ndarray, hsv: np.ndarray, offset) -> _Silhouette | None:
        """Clean up a window's colour ``mask``; ``None`` if too little is left."""
        cfg = self.config
        if cfg.open_size > 1:
            kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (cfg.open_size,) * 2)
            mask = cv2.morphologyEx(mask, cv2.MORPH_OPEN, kernel)
        count, labels, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        if count < 2:
            return None
        areas = stats[1:, cv2.CC_STAT_AREA]
        keep = 1 + np.flatnonzero(areas >= keep_threshold(areas, cfg))
        area = int(stats[keep, cv2.CC_STAT_AREA].sum())
        if area < cfg.min_area:
            return None
        if len(keep) < count - 1:
            mask = np.where(np.isin(labels, keep), np.uint8(255), np.uint8(0))
        x0 = stats[keep, cv2.CC_STAT_LEFT]
        y0 = stats[keep, cv2.CC_STAT_TOP]
        x1 = x0 + stats[keep, cv2.CC_STAT_WIDTH]
        y1 = y0 + stats[keep, cv2.CC_STAT_HEIGHT]
        c0, r0 = offset
        box = (c0 + int(x0.min()), r0 + int(y0.min()), c0 + int(x1.max()), r0 + int(y1.max()))
        return _Silhouette(hsv, offset, mask, area, box)

    # -- one object, both views -------------------------------------------------------------

    def _measure(self, obj: ObjectModel, found) -> Measurement | None:
        """Occlusion-aware axis lines in both views, then the corrected ends (module steps 3-6)."""
        left, right = self.cameras
        moments = [_moments(silhouette) for silhouette in found]
        rough = triangulate(left, right, moments[0][0], moments[1][0])
        depths = [float(cam.rotation[2] @ (rough - cam.position)) for cam in self.cameras]
        if min(depths) <= 0:
            return None
        views = tuple(
            self._view(obj, view, found[view], moments[view], depths[view])
            for view in range(len(found))
        )
        raw = triangulate(left, right, views[0].ends, views[1].ends)
        ends = _correct_ends(
            raw,
            self._eyes,
            obj.radius(np.array([0.0, obj.height])),
            *self._camera_arrays,
            np.array([view.origin for view in views]),
            np.array([view.direction for view in views]),
            np.array([view.extent for view in views]),
            self.config.refine_iterations,
        )
        length = np.linalg.norm(ends[1] - ends[0])
        if not 0.5 * obj.height < length < 1.5 * obj.height:
            return None  # the two views do not agree on one object of this size
        return Measurement(ends.mean(axis=0), (ends[1] - ends[0]) / length, ends, views)

    def _view(self, obj: ObjectModel, view: int, found: _Silhouette, moments, depth: float):
        """Axis line and extremes of ``obj`` in one image (module steps 2-4).

        Args:
            obj: the object.
            view: 0 left, 1 right.
            found: its silhouette.
            moments: ``(centroid (2,) [px], principal direction (2,))`` of the silhouette.
            depth: the object's rough depth along this camera's optical axis [m].
        """
        cfg, key = self.config, (obj.name, view)
        offset = np.asarray(found.offset, dtype=float)
        centroid, direction = moments
        if direction @ self._directions.get(key, np.array([0.0, -1.0])) < 0:
            direction = -direction
        contours, _ = cv2.findContours(found.mask, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        outline = np.concatenate(contours)[:, 0, :] + offset  # (n, 2) (col, row)
        occluded = _NO_OCCLUDER
        if cfg.occluder is not None:
            occluded = cv2.dilate(cfg.occluder.mask(found.hsv), np.ones((3, 3), np.uint8)) > 0
        heights, radii = self._profiles[obj.name]
        origin, free = centroid, 0
        px_per_m = self.cameras[view].intrinsics[0, 0] / depth
        for _ in range(2):  # the second pass splits the sides along the refined axis
            fit = _fit_axis_line(
                outline,
                origin,
                direction,
                heights,
                radii,
                px_per_m,
                occluded,
                offset,
                cfg.end_zone,
                cfg.min_edges,
            )
            if fit[2] == 0:
                break
            origin, direction, free = fit
        self._directions[key] = direction
        return ViewMeasurement(
            area=found.area,
            centroid=centroid,
            origin=origin,
            direction=direction,
            extent=_extremes(outline, origin, direction),
            box=found.box,
            free_edges=free,
        )


def _moments(found: _Silhouette) -> tuple[np.ndarray, np.ndarray]:
    """Centroid ``(2,)`` [px] and principal direction ``(2,)`` (sign arbitrary) of a silhouette."""
    m = cv2.moments(found.mask, binaryImage=True)
    centroid = np.asarray(found.offset, dtype=float) + np.array([m["m10"], m["m01"]]) / m["m00"]
    theta = 0.5 * np.arctan2(2 * m["mu11"], m["mu20"] - m["mu02"])
    return centroid, np.array([np.cos(theta), np.sin(theta)])


@numba.njit(cache=True)
def _extremes(outline: np.ndarray, origin: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """Sub-pixel extremes ``(2,)`` of the ``outline (n, 2)`` along the line ``origin (2,)``,
    ``direction (2,)`` [px, from ``origin``].

    The mean over the outline pixels within one pixel of each extreme: an end edge spans
    several pixels, and their mean moves smoothly with the edge where the single extreme pixel
    jumps by whole pixels (one pixel of disparity is 2 cm of depth at 1.1 m).
    """
    n = outline.shape[0]
    along = np.empty(n)
    for i in range(n):
        along[i] = (outline[i, 0] - origin[0]) * direction[0] + (
            outline[i, 1] - origin[1]
        ) * direction[1]
    low, high = along.min(), along.max()
    sum_low = sum_high = 0.0
    n_low = n_high = 0
    for a in along:
        if a < low + 1.0:
            sum_low += a
            n_low += 1
        if a > high - 1.0:
            sum_high += a
            n_high += 1
    return np.array([sum_low / n_low, sum_high / n_high])


def keep_threshold(areas: np.ndarray, config: PerceptionConfig) -> float:
    """Smallest connected component kept [px], given the components' ``areas``."""
    return max(config.keep_fraction * float(areas.max()), 1.0)


@numba.njit(cache=True)
def _fit_axis_line(
    outline, origin, direction, heights, radii, px_per_m, occluded, offset, end_zone, min_edges
):
    """Least-squares axis line through the free side edges, one apparent radius inside them.

    Compiled (numba): a loop over the outline, where NumPy's per-call overhead on these small
    arrays was most of the tracker's time.

    Args:
        outline: ``(n, 2)`` float outer contour pixels ``(col, row)`` of the silhouette.
        origin: ``(2,)`` a point of the current axis estimate [px].
        direction: ``(2,)`` its unit direction, bottom to top.
        heights: ``(m,)`` the object's profile heights, increasing from 0 [m].
        radii: ``(m,)`` its radius at those heights [m].
        px_per_m: image scale at the object's depth [px/m].
        occluded: ``(h, w)`` bool occluder mask of the searched window; ``(0, 0)`` for none
            (every edge is then the object's own).
        offset: ``(2,)`` ``(col0, row0)`` of that window in the image.
        end_zone: fraction of the length at either end whose edges are not used.
        min_edges: fewest free edges for a fit.

    Returns:
        ``(origin (2,), direction (2,), number of edge pixels used)``; the number is 0 (and the
        line the given one) with fewer than ``min_edges`` edges or a degenerate fit.
    """
    perp = np.array([-direction[1], direction[0]])
    count = outline.shape[0]
    s_all, x_all = np.empty(count), np.empty(count)
    for i in range(count):
        rx, ry = outline[i, 0] - origin[0], outline[i, 1] - origin[1]
        s_all[i] = rx * direction[0] + ry * direction[1]
        x_all[i] = rx * perp[0] + ry * perp[1]
    low, high = s_all.min(), s_all.max()
    # Slices one pixel thick across the axis; each has two edges, its extremes across it.
    n = int(high - low) + 1
    lo, hi = np.full(n, np.inf), np.full(n, -np.inf)
    for i in range(count):
        k = int(s_all[i] - low)
        lo[k] = min(lo[k], x_all[i])
        hi[k] = max(hi[k], x_all[i])
    obj_height = heights[-1]
    span = max(high - low, 1e-9)
    # Sums of the normal equations of x = x0 + slope * s over the free edges.
    used, sum_s, sum_x, sum_ss, sum_sx = 0, 0.0, 0.0, 0.0, 0.0
    for side in (-1.0, 1.0):
        for k in range(n):
            if not np.isfinite(lo[k]):
                continue
            s = low + k + 0.5
            x = lo[k] if side < 0 else hi[k]
            height = (s - low) / span * obj_height
            if not (end_zone * obj_height < height < (1 - end_zone) * obj_height):
                continue
            if not side * x > 0:  # a slice narrower than the axis estimate has no usable edge
                continue
            if occluded.shape[0] > 0:
                # An edge whose outside neighbour is an occluder is where something covers the
                # object, not the object's own side.
                out = x + 1.5 * side
                col = int(np.rint(origin[0] + s * direction[0] + out * perp[0] - offset[0]))
                row = int(np.rint(origin[1] + s * direction[1] + out * perp[1] - offset[1]))
                if 0 <= col < occluded.shape[1] and 0 <= row < occluded.shape[0]:
                    if occluded[row, col]:
                        continue
            axis_x = x - side * np.interp(height, heights, radii) * px_per_m
            used += 1
            sum_s += s
            sum_x += axis_x
            sum_ss += s * s
            sum_sx += s * axis_x
    if used < min_edges:
        return origin, direction, 0
    det = used * sum_ss - sum_s**2
    if not det > 0:
        return origin, direction, 0
    slope = (used * sum_sx - sum_s * sum_x) / det
    x0 = (sum_x - slope * sum_s) / used
    new_direction = (direction + slope * perp) / np.hypot(1.0, slope)
    return origin + x0 * perp, new_direction, used


_NO_OCCLUDER = np.zeros((0, 0), dtype=bool)  # occluded mask when no occluder is set
_RIM_POINTS = 24
_RIM_PHASES = np.linspace(0.0, 2 * np.pi, _RIM_POINTS, endpoint=False)
_RIM_COS, _RIM_SIN = np.cos(_RIM_PHASES), np.sin(_RIM_PHASES)


@numba.njit(cache=True, error_model="numpy")
def _project(intrinsics, rotation, position, point) -> tuple[float, float]:
    """Pixel ``(col, row)`` of world ``point (3,)`` [m]; as :meth:`PinholeCamera.project`."""
    rel = point - position
    cam = rotation @ rel
    pix = intrinsics @ cam
    return pix[0] / pix[2], pix[1] / pix[2]


@numba.njit(cache=True, error_model="numpy")
def _triangulate_pair(intrinsics, rotations, positions, pl, pr) -> np.ndarray:
    """World point ``(3,)`` [m] of pixels ``pl (2,)`` (camera 0) and ``pr (2,)`` (camera 1);
    as :func:`triangulate`, with cameras given as in :func:`_correct_ends`."""
    rays = np.empty((2, 3))
    for c, pix in enumerate((pl, pr)):
        k, r = intrinsics[c], rotations[c]
        x = (pix[0] - k[0, 2]) / k[0, 0]
        y = (pix[1] - k[1, 2]) / k[1, 1]
        rays[c] = x * r[0] + y * r[1] + r[2]
    d1, d2 = rays[0], rays[1]
    w0 = positions[0] - positions[1]
    a, b, c = d1 @ d1, d1 @ d2, d2 @ d2
    d, e = d1 @ w0, d2 @ w0
    denom = a * c - b * b
    t1, t2 = (b * e - c * d) / denom, (a * e - b * d) / denom
    return 0.5 * (positions[0] + t1 * d1 + positions[1] + t2 * d2)


@numba.njit(cache=True, error_model="numpy")
def _rim_fit(ends, radii, intrinsics, rotations, positions, origins, directions, extents):
    """How the rims of ``ends`` appear in the two views, against the views' measurements.

    Per view, the extreme points along the view's axis line of the two rims (circles of
    ``_RIM_POINTS`` points) are predicted, and the observed extremes shifted back by how far
    those lie beyond the projected rim centres.

    Args:
        ends: ``(2, 3)`` bottom and top centres [m].
        radii: ``(2,)`` bottom and top rim radii [m].
        intrinsics, rotations, positions: the cameras, as in :func:`_correct_ends`.
        origins, directions, extents: ``(2, 2)`` per view (left, right), as in
            :class:`ViewMeasurement`.

    Returns:
        ``(shifted (2, 2, 2) [px] (view, end, (col, row)), misfit [px^2])``: the shifted
        extremes, and the summed squares of the predicted extremes' offsets from the observed
        ones along the lines and of the projected centres' distances from the lines (inf for
        a degenerate axis).
    """
    axis = ends[1] - ends[0]
    a = axis / np.sqrt(axis @ axis)
    # u: a unit vector perpendicular to a (a x e for the basis vector e least aligned with a);
    # v = a x u.
    if abs(a[0]) < 0.9:
        u = np.array([0.0, a[2], -a[1]])
    else:
        u = np.array([-a[2], 0.0, a[0]])
    u /= np.sqrt(u @ u)
    v = np.array([a[1] * u[2] - a[2] * u[1], a[2] * u[0] - a[0] * u[2], a[0] * u[1] - a[1] * u[0]])
    shifted = np.empty((2, 2, 2))
    misfit = 0.0
    for c in range(2):
        k, r, p = intrinsics[c], rotations[c], positions[c]
        o, d = origins[c], directions[c]
        for j in range(2):
            col, row = _project(k, r, p, ends[j])
            along = (col - o[0]) * d[0] + (row - o[1]) * d[1]
            across = -(col - o[0]) * d[1] + (row - o[1]) * d[0]
            # The rim's extreme point: lowest along the line for the bottom, highest for the top.
            extreme = np.inf if j == 0 else -np.inf
            for q in range(_RIM_POINTS):
                pc, pr = _project(k, r, p, ends[j] + radii[j] * (_RIM_COS[q] * u + _RIM_SIN[q] * v))
                s = (pc - o[0]) * d[0] + (pr - o[1]) * d[1]
                extreme = min(extreme, s) if j == 0 else max(extreme, s)
            misfit += (extreme - extents[c, j]) ** 2 + across**2
            shifted[c, j] = o + (extents[c, j] - (extreme - along)) * d
    return shifted, misfit if misfit < np.inf else np.inf  # NaN: a degenerate axis


@numba.njit(cache=True, error_model="numpy")
def _refine(
    ends, radii, intrinsics, rotations, positions, origins, directions, extents, iterations
):
    """Rim-extreme correction of the ends (module step 5), from ``ends``.

    Per iteration, the observed extremes shifted back by the rims' predicted offsets
    (:func:`_rim_fit`) are re-triangulated.

    Args:
        ends: ``(2, 3)`` start bottom and top centres [m].
        radii, intrinsics, rotations, positions, origins, directions, extents: as in
            :func:`_rim_fit`.
        iterations: corrections applied.

    Returns:
        ``(ends (2, 3) [m], misfit [px^2])``: the corrected ends and their misfit to the views
        (:func:`_rim_fit`).
    """
    args = (radii, intrinsics, rotations, positions, origins, directions, extents)
    ends = ends.copy()
    for _ in range(iterations):
        shifted, _misfit = _rim_fit(ends, *args)
        for j in range(2):
            ends[j] = _triangulate_pair(
                intrinsics, rotations, positions, shifted[0, j], shifted[1, j]
            )
    return ends, _rim_fit(ends, *args)[1]


@numba.njit(cache=True, error_model="numpy")
def _correct_ends(
    raw, eyes, radii, intrinsics, rotations, positions, origins, directions, extents, iterations
):
    """Ends ``(2, 3)`` [m] corrected for the rims' extremes, from the triangulated extremes.

    The correction has two fixed points, the axis tilted towards or away from the eyes by
    about the same angle (a bottle lying across the view); it starts from ``raw`` and from
    ``raw`` with its axis mirrored in the plane normal to the line of sight, and keeps the
    result whose predicted extremes and centres fit both views better.

    Args:
        raw: ``(2, 3)`` triangulated bottom and top extremes [m].
        eyes: ``(3,)`` the point between the optical centres [m].
        radii: ``(2,)`` bottom and top rim radii [m].
        intrinsics: ``(2, 3, 3)`` left and right ``K`` [px].
        rotations: ``(2, 3, 3)`` left and right world-to-camera rotations.
        positions: ``(2, 3)`` left and right optical centres [m].
        origins: ``(2, 2)`` per view a point of the axis line [px].
        directions: ``(2, 2)`` per view the line's unit direction, bottom to top.
        extents: ``(2, 2)`` per view the extremes along the line from its origin [px].
        iterations: corrections per start.

    Returns:
        ``(2, 3)`` bottom and top centres [m]; NaN for a degenerate axis.
    """
    mid, axis = 0.5 * (raw[0] + raw[1]), raw[1] - raw[0]
    sight = (mid - eyes) / np.sqrt((mid - eyes) @ (mid - eyes))
    axis = axis - 2 * (axis @ sight) * sight
    mirrored = np.empty((2, 3))
    mirrored[0], mirrored[1] = mid - 0.5 * axis, mid + 0.5 * axis
    args = (radii, intrinsics, rotations, positions, origins, directions, extents, iterations)
    ends, misfit = _refine(raw, *args)
    other, other_misfit = _refine(mirrored, *args)
    return other if other_misfit < misfit else ends


def _grow(box, fraction, minimum, width, height) -> tuple[int, int, int, int]:
    """``box`` grown by ``fraction`` of its size (at least ``minimum`` px), inside the image."""
    c0, r0, c1, r1 = box
    dc = max(int(fraction * (c1 - c0)), minimum)
    dr = max(int(fraction * (r1 - r0)), minimum)
    return (max(c0 - dc, 0), max(r0 - dr, 0), min(c1 + dc, width), min(r1 + dr, height))


def _union(a, b) -> tuple[int, int, int, int]:
    return (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))


# --- Tracks over a sequence --------------------------------------------------------------------


@dataclass(frozen=True)
class Gap:
    """Consecutive frames in which an object was not measured.

    Attributes:
        obj: the object's name.
        start: time of the first missing frame [s].
        end: time of the last missing frame [s].
        interpolated: whether it was filled (short, with a measurement on both sides).
    """

    obj: str
    start: float
    end: float
    interpolated: bool


@dataclass(frozen=True, eq=False)
class Tracks:
    """Object tracks over a sequence of stereo pairs.

    Attributes:
        times: ``(n,)`` frame times [s].
        objects: object names, the first axis of the arrays below.
        position: ``(n_objects, n, 3)`` tracked points (axis centre at half height), world
            frame [m]; NaN inside gaps that were not interpolated.
        axis: ``(n_objects, n, 3)`` unit long axes, bottom to top, world frame; NaN likewise.
        angle: ``(n_objects, n)`` axis angle around the gaze vector [rad], unwrapped; NaN
            likewise.
        detected: ``(n_objects, n)`` whether the object was measured in that frame.
        gaze: ``(3, 3)`` gaze frame of the left camera, see :func:`gaze_frame`.
        gaps: every gap, interpolated or not.
    """

    times: np.ndarray
    objects: tuple[str, ...]
    position: np.ndarray
    axis: np.ndarray
    angle: np.ndarray
    detected: np.ndarray
    gaze: np.ndarray
    gaps: tuple[Gap, ...]

    @property
    def long_gaps(self) -> tuple[Gap, ...]:
        """The gaps that were too long to interpolate."""
        return tuple(gap for gap in self.gaps if not gap.interpolated)


def track(tracker: StereoTracker, pairs, times: np.ndarray) -> Tracks:
    """Run ``tracker`` over stereo ``pairs`` and fill short gaps.

    Args:
        tracker: a fresh tracker.
        pairs: iterable of ``(left, right)`` RGB frames, one per entry of ``times``.
        times: ``(n,)`` increasing frame times [s].

    Returns:
        The tracks; gaps up to ``config.max_gap`` are interpolated.

    Raises:
        ImitateError: an object found in no frame (naming it and its colour range), a frame of
            the wrong shape or dtype, or a number of pairs unequal to ``len(times)``.
    """
    times = np.asarray(times, dtype=float)
    objects = tracker.config.objects
    ends = np.full((len(objects), len(times), 2, 3), np.nan)
    count = 0
    for i, (left, right) in enumerate(pairs):
        if i >= len(times):
            raise ImitateError(f"more stereo pairs than the {len(times)} frame times given")
        result = tracker.update(left, right)
        for k, obj in enumerate(objects):
            if result[obj.name] is not None:
                ends[k, i] = result[obj.name].ends
        count = i + 1
    if count != len(times):
        raise ImitateError(f"{count} stereo pairs for {len(times)} frame times; one pair per time")
    return tracks_from_ends(times, objects, ends, gaze_frame(tracker.cameras[0]), tracker.config)


def tracks_from_ends(
    times: np.ndarray,
    objects: tuple[ObjectModel, ...],
    ends: np.ndarray,
    gaze: np.ndarray,
    config: PerceptionConfig,
) -> Tracks:
    """Tracks from the measured bottom and top centres, NaN where not measured.

    Args:
        times: ``(n,)`` [s].
        objects: the tracked objects.
        ends: ``(n_objects, n, 2, 3)`` bottom and top centres [m], NaN where missing.
        gaze: ``(3, 3)`` gaze frame.
        config: tracker settings (``max_gap``).

    Raises:
        ImitateError: an object measured in no frame.
    """
    detected = np.all(np.isfinite(ends), axis=(2, 3))
    for k, obj in enumerate(objects):
        if not detected[k].any():
            c = obj.colour
            raise ImitateError(
                f"object {obj.name!r} was found in none of the {len(times)} stereo pairs: no "
                f"silhouette of at least {config.min_area} px in HSV "
                f"h {c.lower[0]}..{c.upper[0]}, s {c.lower[1]}..{c.upper[1]}, "
                f"v {c.lower[2]}..{c.upper[2]} in both images; check its ColourRange"
            )
    filled, gaps = np.empty_like(ends), []
    for k, obj in enumerate(objects):
        flat, spans = fill_gaps(times, ends[k].reshape(len(times), 6), detected[k], config.max_gap)
        filled[k] = flat.reshape(len(times), 2, 3)
        gaps += [Gap(obj.name, times[i0], times[i1 - 1], done) for i0, i1, done in spans]
    position = filled.mean(axis=2)
    axis = filled[:, :, 1] - filled[:, :, 0]
    axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
    angle = axis_angle(axis, gaze)
    for k in range(len(objects)):
        ok = np.isfinite(angle[k])
        angle[k, ok] = np.unwrap(angle[k, ok])
    return Tracks(
        times=times,
        objects=tuple(obj.name for obj in objects),
        position=position,
        axis=axis,
        angle=angle,
        detected=detected,
        gaze=np.asarray(gaze, dtype=float),
        gaps=tuple(gaps),
    )


def fill_gaps(
    times: np.ndarray, values: np.ndarray, valid: np.ndarray, max_gap: float
) -> tuple[np.ndarray, list[tuple[int, int, bool]]]:
    """Linearly interpolate short runs of missing samples.

    A gap is interpolated when it has a valid sample on both sides no more than ``max_gap``
    apart in time; longer gaps, and gaps at either end, stay NaN.

    Args:
        times: ``(n,)`` increasing [s].
        values: ``(n, d)`` samples; rows where ``valid`` is false are ignored.
        valid: ``(n,)`` bool.
        max_gap: longest interpolated span between the valid samples around a gap [s].

    Returns:
        ``(filled (n, d), gaps)``, ``gaps`` a list of ``(first index, end index exclusive,
        interpolated)``.
    """
    times, valid = np.asarray(times, dtype=float), np.asarray(valid, dtype=bool)
    filled = np.where(valid[:, None], values, np.nan)
    change = np.flatnonzero(np.diff(np.concatenate([[1], valid.astype(int), [1]])))
    gaps = []
    for i0, i1 in zip(change[::2], change[1::2], strict=True):
        inside = 0 < i0 and i1 < len(times)
        short = inside and times[i1] - times[i0 - 1] <= max_gap + 1e-9
        if short:
            w = ((times[i0:i1] - times[i0 - 1]) / (times[i1] - times[i0 - 1]))[:, None]
            filled[i0:i1] = (1 - w) * values[i0 - 1] + w * values[i1]
        gaps.append((int(i0), int(i1), bool(short)))
    return filled, gaps


# --- The observations artifact -----------------------------------------------------------------


@dataclass(frozen=True, eq=False)
class GroundTruth:
    """What the tracker should have seen (simulation only; used for evaluation, never learning).

    Attributes:
        position: ``(n_objects, n, 3)`` true tracked points (axis centre at half height) [m].
        axis: ``(n_objects, n, 3)`` true unit long axes.
        angle: ``(n_objects, n)`` their angle around the gaze vector [rad], unwrapped.
        boundaries: ``(n_demos, 2)`` true start and end of each demonstration [s].
    """

    position: np.ndarray
    axis: np.ndarray
    angle: np.ndarray
    boundaries: np.ndarray


@dataclass(frozen=True, eq=False)
class Observations:
    """Contents of ``observations.npz``.

    Attributes:
        tracks: the tracked objects.
        projections: ``(2, 3, 4)`` left and right camera projection matrices ``K [R | -R c]``.
        image_size: ``(width, height)`` of the tracked frames [px].
        truth: the ground truth, when the frames were simulated.
    """

    tracks: Tracks
    projections: np.ndarray
    image_size: tuple[int, int]
    truth: GroundTruth | None = None


_TRACK_ARRAYS = ("times", "objects", "position", "axis", "angle", "detected", "gaze")


def save_observations(path, observations: Observations):
    """Write ``observations`` to ``path`` (``observations.npz``), atomically."""
    t = observations.tracks
    arrays = {name: getattr(t, name) for name in _TRACK_ARRAYS}
    arrays["objects"] = np.array(t.objects)
    arrays["gap_object"] = np.array([t.objects.index(g.obj) for g in t.gaps], dtype=int)
    arrays["gap_span"] = np.array([(g.start, g.end) for g in t.gaps], dtype=float).reshape(-1, 2)
    arrays["gap_interpolated"] = np.array([g.interpolated for g in t.gaps], dtype=bool)
    arrays["projections"] = observations.projections
    arrays["image_size"] = np.array(observations.image_size)
    if observations.truth is not None:
        for name in ("position", "axis", "angle", "boundaries"):
            arrays[f"truth_{name}"] = getattr(observations.truth, name)
    return save_npz(path, arrays)


def load_observations(path) -> Observations:
    """Read ``observations.npz``; raises ``ImitateError`` naming the file if it is unusable."""
    a = load_npz(path, required=(*_TRACK_ARRAYS, "projections", "image_size", "gap_object"))
    objects = tuple(str(name) for name in a["objects"])
    gaps = tuple(
        Gap(objects[k], float(s), float(e), bool(done))
        for k, (s, e), done in zip(
            a["gap_object"], a["gap_span"], a["gap_interpolated"], strict=True
        )
    )
    tracks = Tracks(
        times=a["times"],
        objects=objects,
        position=a["position"],
        axis=a["axis"],
        angle=a["angle"],
        detected=a["detected"],
        gaze=a["gaze"],
        gaps=gaps,
    )
    truth = None
    if "truth_position" in a:
        truth = GroundTruth(
            a["truth_position"], a["truth_axis"], a["truth_angle"], a["truth_boundaries"]
        )
    width, height = (int(v) for v in a["image_size"])
    return Observations(tracks, a["projections"], (width, height), truth)
