"""Where the stick's lower end is relative to the glass: the one measure of the insertion, for
the env's ``info`` (:func:`stick_end`) and, step by step in a replay, :class:`InsertGeometry`.

Both are expressed in the glass's frame, so that depths below the rim and offsets from the
glass's axis do not depend on how the glass is held. The lower end is whichever end of the stick
is lower in that frame (its bottom, as the teacher holds it). It is in the glass when it is below
the rim's plane, above the glass's floor and nearer to the glass's axis than the inner wall at
that height; its depth in the glass is then its depth below the rim, else 0.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, ClassVar

import mujoco
import numpy as np

from imitate.models import objects

if TYPE_CHECKING:
    from imitate.envs.bimanual import BimanualEnv

__all__ = ["InsertGeometry", "stick_end"]

_GLASS = objects.GLASS_SHAPE
_INNER = np.transpose([(r - _GLASS.wall / 2, h) for r, h in _GLASS.profile])  # radius, height


def stick_end(data: mujoco.MjData) -> tuple[float, float, float, float]:
    """The stick's lower end relative to the glass, at ``data``'s kinematics.

    Returns:
        ``(depth, offset, inside, tilt)``: its depth below the rim's plane [m] (negative above
        it), its distance from the glass's axis [m], its depth in the glass [m] (the depth
        when inside, else 0) and the angle between the stick's and the glass's axes [deg].
    """
    stick, glass = data.body(objects.STICK), data.body(objects.GLASS)
    stick_axes, glass_axes = stick.xmat.reshape(3, 3), glass.xmat.reshape(3, 3)
    ends = stick.xpos + np.outer((0.0, objects.STICK_SHAPE.height), stick_axes[:, 2])
    local = (ends - glass.xpos) @ glass_axes
    end = local[np.argmin(local[:, 2])]
    depth, offset = _GLASS.height - end[2], float(np.hypot(end[0], end[1]))
    radius = np.interp(end[2], _INNER[1], _INNER[0])
    inside = depth > 0 and end[2] > _GLASS.wall and offset < radius
    tilt = np.degrees(np.arccos(np.clip(stick_axes[:, 2] @ glass_axes[:, 2], -1.0, 1.0)))
    return float(depth), offset, float(depth) if inside else 0.0, float(tilt)


class InsertGeometry:
    """Records, at every call (``watcher(env)``), the stick's lower end relative to the glass
    (:func:`stick_end`)."""

    # What :meth:`summary` returns, each key with its unit and meaning (the report's
    # ``replay.insert_geometry.*``; ``None`` where not seen).
    KEYS: ClassVar[Mapping[str, tuple[str, str]]] = {
        "depth_m": (
            "m",
            "in the first replay, at the deepest point in the glass: the lower end's depth below "
            "the rim, in the glass's frame",
        ),
        "offset_m": (
            "m",
            "its distance from the glass's axis (the inner radius is 34 mm at the bottom, 40 mm at "
            "the rim)",
        ),
        "tilt_deg": ("deg", "the angle between the stick's and glass's axes"),
        "entry_offset_m": (
            "m",
            "the lower end's distance from the glass's axis as it went below the rim",
        ),
        "offset_max_m": ("m", "its largest distance from the axis in the glass"),
        "seconds_inside": ("s", "time the lower end was in the glass"),
        "lowest_below_rim_m": (
            "m",
            "the lowest the lower end came, below the rim's plane, in the glass or not",
        ),
    }

    def __init__(self) -> None:
        self._rows: list[tuple[float, float, float, float]] = []
        self._dt = 0.0

    def __call__(self, env: BimanualEnv) -> None:
        self._rows.append(stick_end(env.data))
        self._dt = env.dt

    def summary(self) -> dict[str, float | None]:
        """At the deepest point in the glass: the depth below the rim and the offset from the
        glass's axis [m], the angle between the axes [deg]; the offset as the end went below
        the rim [m], the largest offset in the glass [m] and the time in the glass [s]; the
        lowest the end came over the whole replay, below the rim [m]. ``None`` where the end
        never was in the glass."""
        rows = np.array(self._rows).reshape(-1, 4)
        depth, offset, inside, tilt = rows.T
        lowest = {"lowest_below_rim_m": float(depth.max()) if len(depth) else None}
        steps = np.flatnonzero(inside > 0)
        if len(steps) == 0:
            return {**dict.fromkeys(self.KEYS), **lowest}
        deepest = int(np.argmax(inside))
        return {
            "depth_m": float(inside[deepest]),
            "offset_m": float(offset[deepest]),
            "tilt_deg": float(tilt[deepest]),
            "entry_offset_m": float(offset[steps[0]]),
            "offset_max_m": float(offset[steps].max()),
            "seconds_inside": float(len(steps) * self._dt),
            **lowest,
        }
