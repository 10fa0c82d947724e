"""Where the stream meets the glass: the bottle's mouth relative to the glass rim while the
liquid leaves the bottle, and where each particle first falls through the rim's plane, recorded
step by step in a replay (an ``on_step`` callback).

The mouth is the centre of the bottle's opening, the rim the centre of the glass's, both on the
objects' axes; both are expressed in the glass's frame, so that heights above the rim and
offsets from the glass's axis do not depend on how the glass is held. The pour is the span from
the first to the last step at which the bottle holds fewer particles than the step before. A
particle out of the bottle that falls through the rim's plane within the rim's inner radius
(40 mm) lands in the glass; one that falls through it further out misses (or hits the rim).
Particles still in the bottle are not counted: the bottle itself may pass through the plane.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

import numpy as np

from imitate.envs.pour.env import PouringEnv
from imitate.models import objects

__all__ = ["PourGeometry"]


class PourGeometry:
    """Records, at every call (``on_step(env)``), the bottle's tilt from upright [deg], the
    mouth's position relative to the rim centre in the glass's frame ``(3,)`` [m] and the share
    of particles in the bottle."""

    # What :meth:`summary` returns, each key with its unit and meaning (the report's
    # ``replay.pour_geometry.*``; ``None`` where not seen).
    KEYS: ClassVar[Mapping[str, tuple[str, str]]] = {
        "mouth_above_rim_min_m": (
            "m",
            "in the first replay, while liquid leaves the bottle: the lowest height of the bottle's"
            " mouth above the glass rim, in the glass's frame",
        ),
        "mouth_above_rim_median_m": ("m", "its median"),
        "mouth_offset_median_m": (
            "m",
            "median distance of the mouth from the glass's axis (the inner rim radius is 40 mm)",
        ),
        "mouth_offset_max_m": ("m", "its largest"),
        "tilt_max_deg": ("deg", "the bottle's largest tilt from upright"),
        "pour_seconds": ("s", "from the first to the last step at which liquid left the bottle"),
        "stream_offset_median_m": (
            "m",
            "median distance from the glass's axis at which the particles first fell through the "
            "rim's plane",
        ),
        "stream_centre_offset_m": ("m", "distance of their mean crossing point from the axis"),
        "stream_inside_share": (
            "1",
            "share of them that fell through within the rim's inner radius",
        ),
    }

    def __init__(self) -> None:
        self._rows: list[tuple[float, ...]] = []
        self._dt = 0.0
        self._above: np.ndarray | None = None  # particles' positions in the rim's frame
        self._crossed: dict[int, np.ndarray] = {}  # particle: (x, y) where it first fell through

    def __call__(self, env: PouringEnv) -> None:
        d = env.data
        bottle, glass = d.body(objects.BOTTLE), d.body(objects.GLASS)
        bottle_axes, glass_axes = bottle.xmat.reshape(3, 3), glass.xmat.reshape(3, 3)
        mouth = bottle.xpos + objects.BOTTLE_SHAPE.height * bottle_axes[:, 2]
        rim = glass.xpos + objects.GLASS_SHAPE.height * glass_axes[:, 2]
        local = (mouth - rim) @ glass_axes
        tilt = np.degrees(np.arccos(np.clip(bottle_axes[2, 2], -1.0, 1.0)))
        in_bottle = env.particles_in(objects.BOTTLE)
        self._rows.append((tilt, *local, float(np.mean(in_bottle)) if len(in_bottle) else 0.0))
        self._dt = env.dt
        particles = (env.particle_positions() - rim) @ glass_axes
        if self._above is not None:
            was, now = self._above, particles
            for i in np.flatnonzero((was[:, 2] > 0) & (now[:, 2] <= 0) & ~in_bottle):
                if i not in self._crossed:
                    share = was[i, 2] / (was[i, 2] - now[i, 2])
                    self._crossed[int(i)] = was[i, :2] + share * (now[i, :2] - was[i, :2])
        self._above = particles

    def summary(self) -> dict[str, float | None]:
        """Over the pour: the mouth's height above the rim (min, median) and its offset from the
        glass's axis (median, max) [m], the largest tilt [deg] and the pour's duration [s]; where
        the particles first fell through the rim's plane: their median distance from the axis,
        the distance of their mean point from it [m] and the share of them within the rim's inner
        radius. ``None`` where no particle left the bottle or fell through."""
        rows = np.array(self._rows)
        left: np.ndarray | list[int]  # steps where particles left the bottle
        left = np.flatnonzero(np.diff(rows[:, 4]) < 0) + 1 if len(rows) > 1 else []
        crossings = np.array(list(self._crossed.values())).reshape(-1, 2)
        distance = np.hypot(crossings[:, 0], crossings[:, 1])
        inner = objects.GLASS_SHAPE.profile[-1][0] - objects.GLASS_SHAPE.wall / 2
        stream: dict[str, float | None] = {
            key: None for key in self.KEYS if key.startswith("stream_")
        }
        if len(crossings):
            stream = {
                "stream_offset_median_m": float(np.median(distance)),
                "stream_centre_offset_m": float(np.hypot(*crossings.mean(axis=0))),
                "stream_inside_share": float(np.mean(distance < inner)),
            }
        if len(left) == 0:
            return {**dict.fromkeys(self.KEYS), **stream}
        pour = rows[left[0]: left[-1] + 1]
        height, offset = pour[:, 3], np.hypot(pour[:, 1], pour[:, 2])
        return {
            "mouth_above_rim_min_m": float(height.min()),
            "mouth_above_rim_median_m": float(np.median(height)),
            "mouth_offset_median_m": float(np.median(offset)),
            "mouth_offset_max_m": float(offset.max()),
            "tilt_max_deg": float(rows[:, 0].max()),
            "pour_seconds": float(len(pour) * self._dt),
            **stream,
        }
