"""Stereo colour tracking of a task's objects from the robot's head cameras (paper II).

Per object and per image of a stereo pair:

1. **Segmentation**: HSV thresholds (:class:`~imitate.perception.colour.ColourRange`) in a
   window around the object's last detection (a coarse search of the whole image acquires or
   re-acquires it), a morphological opening, the connected components that are not specks.
2. **Moments**: centroid and principal axis; the axis's sign (bottom to top) is carried from
   frame to frame, starting from "top up in the image".
3. **Occlusion-aware axis line**: a hand covering part of an object drags its centroid and
   principal axis. The silhouette is cut into slices across its axis; each slice edge that
   borders the background (not the occluder's colour, not near the ends) lies one apparent
   radius from the axis (the object's profile, :class:`~imitate.perception.colour.ObjectModel`,
   at its depth); a least-squares line through these is the image of the axis.
4. **Extremes** of the silhouette along that line, the images of the bottom and top rims,
   sub-pixel: the mean of the outline within a pixel of each extreme.

Then per object, from the two views:

5. **Ends**: the extremes are triangulated, then corrected for a rim's extreme point not being
   its centre (:mod:`imitate.perception._rim`): the rims of the current estimate are projected,
   the observed extremes shifted back by how far the predicted ones lie beyond the rim centres,
   and re-triangulated. With the axis across the view (near the epipolar plane) this has two
   self-consistent results, the axis tilted towards or away from the eyes; both starts are run
   and the one that better fits both views is kept. Both can fit exactly (a wrong tilt), and
   depth then rests on the two ends alone, so it is less accurate than for an upright object.
6. **Tracked point**: the middle of the two rim centres, the centre of the object's axis at
   half its height (as the ground truth). **Axis**: the unit vector bottom to top. **Angle**
   around the gaze vector: ``atan2(a . g_1, a . g_0)`` in the gaze frame ``g``
   (:func:`imitate.taskspace.image_angle`, :func:`imitate.taskspace.gaze_of_camera`).

Steps 3-5 are why the blob centroids are not simply triangulated: a silhouette's centroid is not
at half height, and a hand shifts it differently in the two views. The loops over the outline
(steps 3-4, :mod:`imitate.perception._outline`) and step 5 are compiled with numba (on a
process's first call, or loaded from numba's on-disk cache); the rest is OpenCV.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np

from imitate.errors import ImitateError
from imitate.perception._outline import _extremes, _fit_axis_line
from imitate.perception._rim import _correct_ends
from imitate.perception.camera import PinholeCamera, triangulate
from imitate.perception.colour import SKIN, ColourRange, ObjectModel, object_models


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


def perception_config(names: Sequence[str], **overrides) -> PerceptionConfig:
    """The tracker's settings for the objects ``names`` (:func:`object_models`; ``overrides``
    replace any field)."""
    return PerceptionConfig(objects=object_models(names), **overrides)


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
        intrinsics, rotations, positions = (
            np.ascontiguousarray([getattr(cam, name) for cam in self.cameras], dtype=float)
            for name in ("intrinsics", "rotation", "position")
        )
        self._camera_arrays = (intrinsics, rotations, positions)
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


def keep_threshold(areas: np.ndarray, config: PerceptionConfig) -> float:
    """Smallest connected component kept [px], given the components' ``areas``."""
    return max(config.keep_fraction * float(areas.max()), 1.0)


_NO_OCCLUDER = np.zeros((0, 0), dtype=bool)  # occluded mask when no occluder is set


def _grow(box, fraction, minimum, width, height) -> tuple[int, int, int, int]:
    """``box`` grown by ``fraction`` of its size (at least ``minimum`` px), inside the image."""
    c0, r0, c1, r1 = box
    dc = max(int(fraction * (c1 - c0)), minimum)
    dr = max(int(fraction * (r1 - r0)), minimum)
    return (max(c0 - dc, 0), max(r0 - dr, 0), min(c1 + dc, width), min(r1 + dr, height))


def _union(a, b) -> tuple[int, int, int, int]:
    return (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))
