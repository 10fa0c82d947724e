"""Object tracks over a sequence of stereo pairs, their gaps, and the observation as arrays.

:func:`track` runs a :class:`~imitate.perception.tracker.StereoTracker` over the pairs; frames
in which an object is not found are gaps, which :func:`fill_gaps` interpolates when short and
reports when long. :class:`Observations` (tracks, cameras, and the ground truth when the frames
were simulated) is what the observation stage writes, as :meth:`Observations.to_arrays`.
"""

from __future__ import annotations

import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass

import cv2
import numpy as np

from imitate.errors import ImitateError
from imitate.perception.colour import ObjectModel
from imitate.perception.tracker import PerceptionConfig, StereoTracker
from imitate.taskspace import gaze_of_camera, image_angle


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
        gaze: ``(3, 3)`` gaze frame of the left camera
            (:func:`~imitate.taskspace.gaze_of_camera`).
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


def track(tracker: StereoTracker, pairs, times: np.ndarray, timing: dict | None = None) -> Tracks:
    """Run ``tracker`` over stereo ``pairs`` and fill short gaps.

    Args:
        tracker: a fresh tracker.
        pairs: iterable of ``(left, right)`` RGB frames, one per entry of ``times``.
        times: ``(n,)`` increasing frame times [s].
        timing: if given, ``timing["track"]`` accumulates the time spent tracking and
            triangulating (not in producing the pairs) [s].

    Returns:
        The tracks; gaps up to ``config.max_gap`` are interpolated.

    Raises:
        ImitateError: an object found in no frame (naming it and its colour range), a frame of
            the wrong shape or dtype, or a number of pairs unequal to ``len(times)``.
    """
    times = np.asarray(times, dtype=float)
    objects = tracker.config.objects
    ends = np.full((len(objects), len(times), 2, 3), np.nan)
    count, elapsed = 0, 0.0
    with _one_opencv_thread():
        for i, (left, right) in enumerate(pairs):
            if i >= len(times):
                raise ImitateError(f"more stereo pairs than the {len(times)} frame times given")
            start = time.perf_counter()
            result = tracker.update(left, right)
            elapsed += time.perf_counter() - start
            for k, obj in enumerate(objects):
                if (measurement := result[obj.name]) is not None:
                    ends[k, i] = measurement.ends
            count = i + 1
    if timing is not None:
        timing["track"] = timing.get("track", 0.0) + elapsed
    if count != len(times):
        raise ImitateError(f"{count} stereo pairs for {len(times)} frame times; one pair per time")
    gaze = gaze_of_camera(tracker.cameras[0].rotation)
    return tracks_from_ends(times, objects, ends, gaze, tracker.config)


@contextmanager
def _one_opencv_thread() -> Iterator[None]:
    """OpenCV's functions in the calling thread meanwhile (a process-wide setting, restored after).

    The tracker's calls work on small windows, which OpenCV would otherwise split across every
    core: on a 16-core machine the tracking took 7 to 8 times its wall time in processor time,
    which the rendering thread beside it needs. The results are the same.
    """
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        yield
    finally:
        cv2.setNumThreads(threads)


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
    angle = image_angle(axis, gaze)
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
    """What the robot saw: the tracks and its cameras (``observations.npz``).

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

    @staticmethod
    def array_names() -> tuple[str, ...]:
        """Names of the arrays :meth:`to_arrays` always writes (``truth_*`` only with the
        ground truth)."""
        return (
            *_TRACK_ARRAYS, "projections", "image_size", "gap_object", "gap_span",
            "gap_interpolated",
        )

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The observation as named arrays: the tracks' (``objects`` as strings), the gaps'
        (``gap_object`` index into ``objects``, ``gap_span`` ``(n_gaps, 2)`` [s],
        ``gap_interpolated``), the cameras' and, if known, the truth's (``truth_*``)."""
        t = self.tracks
        arrays = {name: getattr(t, name) for name in _TRACK_ARRAYS}
        arrays["objects"] = np.array(t.objects)
        arrays["gap_object"] = np.array([t.objects.index(g.obj) for g in t.gaps], dtype=int)
        arrays["gap_span"] = np.array([(g.start, g.end) for g in t.gaps], dtype=float).reshape(
            -1, 2
        )
        arrays["gap_interpolated"] = np.array([g.interpolated for g in t.gaps], dtype=bool)
        arrays["projections"] = self.projections
        arrays["image_size"] = np.array(self.image_size)
        if self.truth is not None:
            for name in ("position", "axis", "angle", "boundaries"):
                arrays[f"truth_{name}"] = getattr(self.truth, name)
        return arrays

    @classmethod
    def from_arrays(cls, a: Mapping[str, np.ndarray]) -> Observations:
        """The observation stored by :meth:`to_arrays`."""
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
        return cls(tracks, a["projections"], (width, height), truth)


_TRACK_ARRAYS = ("times", "objects", "position", "axis", "angle", "detected", "gaze")
