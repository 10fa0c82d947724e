"""Cutting continuous object tracks into demonstrations at stillness (paper II).

"If the observed objects are held still for a defined duration, the current demonstration is
finished and the next one starts when the objects are moving again." Held still means neither
moved nor turned: a frame is still when it lies in a window of ``min_still`` seconds over which
every held object's (smoothed) tracked point stays within a box of ``still_range`` and its angle
around the gaze vector within ``still_turn`` (a place stands still through a demonstration; the
teacher may move it between two). Spread over a window separates a slow movement
(an object turning slowly while the task is done, a slow return) from tracking noise much
better than an instantaneous speed does. A demonstration is a stretch between still frames
lasting at least ``min_moving``.

Its boundaries are then placed where the movement really starts and stops. A hand leaves rest
with about constant acceleration, so the distance from the rest position grows with the square
of time and its square root linearly: a line through the square root of the distance, where it
is between ``onset_distance`` and eight times that, extended to zero gives the onset (and, run
backwards from the next rest position, the stop). This puts the boundary on the motion's onset
rather than on the later moment the spread test notices it.

:func:`task_demo` turns a demonstration into the task-space samples that learning takes.
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter1d, minimum_filter1d
from scipy.signal import savgol_filter

from imitate import defaults
from imitate.errors import ImitateError
from imitate.models.shapes import SHAPES
from imitate.perception import Tracks
from imitate.taskspace import OBJECTS, TaskSpace


@dataclass(frozen=True)
class StillnessConfig:
    """Settings of the stillness segmentation.

    Attributes:
        min_still: a still window lasts this long [s]; stillness shorter than this does not end
            a demonstration.
        still_range: largest extent of an object's path over a still window [m] (the norm of
            its x, y, z ranges); above the tracking noise and tremor.
        still_turn: largest range of an object's angle over a still window [rad].
        min_moving: movements shorter than this are not demonstrations [s].
        smoothing: Savitzky-Golay window smoothing the tracks first [s].
        onset_distance: distance from rest [m] where the onset fit begins (above the smoothed
            noise); the fit uses distances up to eight times this.
    """

    min_still: float = 0.5
    still_range: float = 0.012
    still_turn: float = np.radians(3.0)
    min_moving: float = 1.0
    smoothing: float = defaults.SMOOTHING
    onset_distance: float = 0.003

    def __post_init__(self):
        for name in (
            "min_still",
            "still_range",
            "still_turn",
            "min_moving",
            "smoothing",
            "onset_distance",
        ):
            if not getattr(self, name) > 0:
                raise ImitateError(f"{name}={getattr(self, name)!r} not accepted: a value > 0")

    def describe(self) -> str:
        """The settings, for messages."""
        return (
            f"min_still={self.min_still} s, still_range={self.still_range} m, still_turn="
            f"{np.degrees(self.still_turn):.1f} deg, min_moving={self.min_moving} s"
        )


@dataclass(frozen=True, eq=False)
class Demonstration:
    """One demonstration, cut from the tracks with its still parts trimmed.

    Attributes:
        start: time of the motion's onset [s] (session time).
        end: time it stops [s].
        times: ``(m,)`` frame times inside ``[start, end]`` [s].
        position: ``(n_objects, m, 3)`` tracked points [m].
        axis: ``(n_objects, m, 3)`` unit long axes.
        angle: ``(n_objects, m)`` angles around the gaze vector [rad].
    """

    start: float
    end: float
    times: np.ndarray
    position: np.ndarray
    axis: np.ndarray
    angle: np.ndarray


def smoothed(tracks: Tracks, smoothing: float) -> tuple[np.ndarray, np.ndarray]:
    """Savitzky-Golay (quadratic) smoothed positions ``(n_objects, n, 3)`` and angles.

    Gaps left in the tracks are bridged linearly for this purpose.

    Raises:
        ImitateError: tracks too short for the smoothing window, or an object tracked in none
            of the frames.
    """
    t = tracks.times
    window = max(5, _frames(t, smoothing) | 1)
    if window > len(t):
        raise ImitateError(
            f"tracks of {len(t)} frames are too short to segment with smoothing={smoothing} s "
            f"({window} frames)"
        )
    out = []
    for tracked in (tracks.position, tracks.angle[..., None]):
        ok = np.all(np.isfinite(tracked), axis=-1)
        out.append(_savgol(_bridged(t, tracked, ok), window))
    return out[0], out[1][..., 0]


def _bridged(times: np.ndarray, values: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """A copy of ``values`` ``(n_objects, n, c)`` where the samples not ``ok`` ``(n_objects,
    n)`` are interpolated linearly in ``times`` ``(n,)`` [s] from the others, held at the ends.

    Raises:
        ImitateError: an object has no sample ``ok``.
    """
    values = values.copy()
    for k in range(len(values)):
        if not ok[k].any():
            raise ImitateError(
                f"object {k} was tracked in none of the frames at {times[0]:.2f}..{times[-1]:.2f}"
                " s; see figures/observation.png"
            )
        for c in range(values.shape[-1]):
            values[k, :, c] = np.interp(times, times[ok[k]], values[k, ok[k], c])
    return values


def _savgol(values: np.ndarray, frames: int) -> np.ndarray:
    """``values`` ``(n_objects, n, c)`` smoothed over time by a quadratic Savitzky-Golay filter
    of ``frames`` (odd, 5..n)."""
    return savgol_filter(values, frames, 2, axis=1)


def still_frames(
    times: np.ndarray, position: np.ndarray, angle: np.ndarray, config: StillnessConfig
) -> np.ndarray:
    """Which frames ``(n,)`` lie in a still window (see the module docstring).

    Args:
        times: ``(n,)`` [s].
        position: ``(n_objects, n, 3)`` smoothed tracked points [m].
        angle: ``(n_objects, n)`` smoothed angles [rad].
        config: the stillness settings.
    """
    width = max(_frames(times, config.min_still), 3) | 1  # odd: windows centred on frames

    def spread(values):
        return maximum_filter1d(values, width, axis=1) - minimum_filter1d(values, width, axis=1)

    extent = np.linalg.norm(spread(position), axis=-1).max(axis=0)
    turn = spread(angle).max(axis=0)
    centred = (extent < config.still_range) & (turn < config.still_turn)
    # A frame is still if any still window covers it.
    return maximum_filter1d(centred.astype(np.uint8), width).astype(bool)


def find_demonstrations(
    times: np.ndarray, position: np.ndarray, angle: np.ndarray, config: StillnessConfig
) -> np.ndarray:
    """Start and end times ``(n_demos, 2)`` [s] of the movements separated by stillness.

    Args:
        times: ``(n,)`` increasing frame times [s].
        position: ``(n_objects, n, 3)`` smoothed tracked points [m].
        angle: ``(n_objects, n)`` smoothed angles [rad].
        config: the stillness settings.
    """
    still = still_frames(times, position, angle, config)
    edges = np.flatnonzero(np.diff(np.concatenate([[1], still.astype(int), [1]])))
    found = []
    for i0, i1 in zip(edges[::2], edges[1::2], strict=True):  # moving frames [i0, i1)
        if times[i1 - 1] - times[i0] < config.min_moving or i0 == 0 or i1 == len(times):
            continue  # too short, or not framed by stillness on both sides
        start = _onset(times, position, still, i0, +1, config.onset_distance)
        end = _onset(times, position, still, i1 - 1, -1, config.onset_distance)
        found.append((start, end))
    return np.array(found, dtype=float).reshape(-1, 2)


def _onset(times, position, still, index: int, step: int, distance: float) -> float:
    """Onset (``step`` +1) or stop (``step`` -1) time of the movement next to frame ``index``.

    ``index`` is the first (last) moving frame. The rest position is the median over the still
    run before (after) it; see the module docstring for the fit. Without a usable fit the
    boundary stays at ``index``'s time.
    """
    n = len(times)
    rest_frames = []
    i = index - step
    while 0 <= i < n and still[i]:
        rest_frames.append(i)
        i -= step
    rest = np.median(position[:, rest_frames], axis=1)  # (n_objects, 3)
    dist = np.linalg.norm(position - rest[:, None], axis=-1).max(axis=0)
    i = index
    while 0 <= i - step < n and dist[i - step] >= distance:
        i -= step  # back to where the distance rises through onset_distance
    fit = []
    while 0 <= i < n and dist[i] < _FIT_SPAN * distance:
        fit.append(i)
        i += step
    if len(fit) < 2:
        return float(times[index])
    slope, intercept = np.polyfit(times[fit], np.sqrt(dist[fit]), 1)
    if not slope * step > 0:
        return float(times[index])
    return float(-intercept / slope)


_FIT_SPAN = 8.0  # the onset fit uses distances from onset_distance up to this multiple


def _frames(times: np.ndarray, duration: float) -> int:
    """Number of frames spanning ``duration`` [s] at the frame rate of ``times``."""
    dt = float(np.median(np.diff(times))) if len(times) > 1 else 1.0
    return int(round(duration / dt))


def segment(tracks: Tracks, config: StillnessConfig = StillnessConfig()) -> list[Demonstration]:
    """The demonstrations in ``tracks``, still parts trimmed.

    Raises:
        ImitateError: fewer than 2 demonstrations found; the message names the settings.
    """
    position, angle = smoothed(tracks, config.smoothing)
    held = slice(0, len(OBJECTS))  # what the teacher moves (its places move between demos)
    bounds = find_demonstrations(tracks.times, position[held], angle[held], config)
    if len(bounds) < 2:
        raise ImitateError(
            f"found {len(bounds)} demonstration(s) in {tracks.times[-1] - tracks.times[0]:.1f} s "
            f"of tracks, at least 2 needed; stillness settings: {config.describe()} (a "
            f"shorter min_still or a larger still_range finds more)"
        )
    demos = []
    for start, end in bounds:
        inside = (tracks.times >= start) & (tracks.times <= end)
        demos.append(
            Demonstration(
                start=float(start),
                end=float(end),
                times=tracks.times[inside],
                position=tracks.position[:, inside],
                axis=tracks.axis[:, inside],
                angle=tracks.angle[:, inside],
            )
        )
    return demos


def task_demo(
    demo: Demonstration, objects: tuple[str, ...], gaze: np.ndarray, space: TaskSpace,
    places: Mapping[str, np.ndarray], *, smoothing: float, rate: float,
) -> np.ndarray:
    """The task-space demonstration (in the task's ``space``) learned from ``demo``.

    Samples perception left missing (gaps too long to fill) are bridged linearly in time, the
    tracks smoothed by a quadratic Savitzky-Golay filter over ``smoothing`` [s] (not at all
    where that is under 5 frames or longer than the demonstration), and the tracked points
    (axis centres) moved back to the object frames (bottoms).

    Args:
        demo: The demonstration; ``objects`` names the first axis of its arrays.
        objects: Object names, the tool's first, then the target's, then the places'.
        gaze: ``(3, 3)`` gaze frame of the observation.
        space: The task's space.
        places: Where each place stands, ``(3,)`` [m] (:func:`place_positions`).
        smoothing: Savitzky-Golay window [s]; 0: none.
        rate: Frame rate of the tracks [Hz].

    Returns:
        ``(n, m)`` task-space samples.

    Raises:
        ImitateError: the tool or the target was tracked in none of the demonstration's frames.
    """
    held = slice(0, len(OBJECTS))
    ok = np.all(np.isfinite(demo.position[held]) & np.isfinite(demo.axis[held]), axis=-1)
    position, axis = (_bridged(demo.times, v[held], ok) for v in (demo.position, demo.axis))
    axis = _unit(axis)
    frames = int(round(smoothing * rate)) | 1
    if 5 <= frames <= position.shape[1]:
        position, axis = _savgol(position, frames), _unit(_savgol(axis, frames))
    tracks: dict[str, tuple[np.ndarray, np.ndarray | None]] = {
        role: (position[k] - axis[k] * SHAPES[name].height / 2, axis[k])
        for k, (role, name) in enumerate(zip(OBJECTS, objects[held], strict=True))
    }
    tracks.update({name: (np.broadcast_to(p, position[0].shape), None)
                   for name, p in places.items()})
    return space(tracks, gaze)


def place_positions(
    segments: Sequence[Demonstration], objects: tuple[str, ...]
) -> list[dict[str, np.ndarray]]:
    """Where each place (the ``objects`` after the tool and the target) stands through each of
    ``segments``, ``(3,)`` [m]: the median of its bottom over the segment's frames it was seen
    in (it stands upright and still while the teacher demonstrates); over every segment's frames
    for a segment it was hidden through, with a warning.

    Raises:
        ImitateError: a place seen in none of their frames.
    """
    found: list[dict[str, np.ndarray]] = [{} for _ in segments]
    for k, name in enumerate(objects[len(OBJECTS):], start=len(OBJECTS)):
        seen = [d.position[k][np.all(np.isfinite(d.position[k]), axis=-1)] for d in segments]
        if not sum(map(len, seen)):
            raise ImitateError(f"place {name} was tracked in none of the demonstrations' frames; "
                               "see figures/observation.png")
        bottom = (0.0, 0.0, SHAPES[name].height / 2)
        overall = np.median(np.concatenate(seen), axis=0) - bottom
        for i, points in enumerate(seen):
            if not len(points):
                warnings.warn(f"place {name} was hidden through demonstration {i}: where it "
                              "stood over all the demonstrations taken", stacklevel=2)
            found[i][name] = np.median(points, axis=0) - bottom if len(points) else overall
    return found


def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def task_demos(
    segments: Sequence[Demonstration], objects: tuple[str, ...], gaze: np.ndarray,
    space: TaskSpace, *, smoothing: float,
) -> tuple[list[np.ndarray], float]:
    """The demonstrations ``segments`` in the task ``space`` (:func:`task_demo` each) and their
    rate [Hz] (the first one's median frame rate): what :func:`imitate.learn` takes."""
    rate = 1.0 / float(np.median(np.diff(segments[0].times)))
    places = place_positions(segments, objects)
    return [task_demo(d, objects, gaze, space, p, smoothing=smoothing, rate=rate)
            for d, p in zip(segments, places, strict=True)], rate
