"""``MarkedPouringEnv``: the humanoid pours from the bottle in its right hand into the glass in its
left, holding the glass over a marker that stands on the table.

As ``PouringEnv`` (:mod:`imitate.envs.pour.env`: actions, observations, rewards, episode end,
reset options), with a marker (a lime peg, :data:`imitate.models.shapes.MARKER`) standing at
``marker_x``, ``marker_y`` on the table. ``info`` adds ``marker_offset``: the largest horizontal
distance of the glass's bottom centre from the marker's axis over the steps at which liquid left
the bottle since the reset [m] (before any did: the distance now); ``is_success`` asks for a
pour over the marker (:func:`imitate.envs.marked.outcome.over`).

## Arguments
``PouringEnv``'s, and ``marker_x``, ``marker_y``: where the marker stands [m] (defaults and ranges
in :data:`imitate.envs.marked.options.OPTIONS`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, ClassVar

import numpy as np

from imitate.envs import assembly
from imitate.envs.marked.options import OPTIONS
from imitate.envs.marked.outcome import over
from imitate.envs.pour.env import PouringEnv
from imitate.models import objects

__all__ = ["MarkedPouringEnv"]


class MarkedPouringEnv(PouringEnv):
    """The marked pour in full physics (see the module docstring)."""

    task = "marked"
    measures: ClassVar[Mapping[str, tuple[str, str]]] = {
        **PouringEnv.measures,
        "marker_offset": ("m", "the glass's largest distance from the marker's axis while "
                               "liquid left the bottle, horizontally"),
    }
    _in_bottle: float | None
    _offset: float | None

    def __init__(
        self,
        *args: Any,
        marker_x: float = OPTIONS["marker_x"].default,
        marker_y: float = OPTIONS["marker_y"].default,
        **kwargs: Any,
    ):
        super().__init__(*args, marker_x=marker_x, marker_y=marker_y, **kwargs)
        self._marker = self.data.body(objects.MARKER)

    @classmethod
    def scene_config(
        cls, teacher: bool = False, obstacles: tuple[assembly.Obstacle, ...] = (),
        particles: int = 60,
        marker_x: float = OPTIONS["marker_x"].default,
        marker_y: float = OPTIONS["marker_y"].default,
    ) -> assembly.SceneConfig:
        """The pour's scene with the marker where ``marker_x``, ``marker_y`` put it."""
        config = super().scene_config(teacher, obstacles, particles)
        marker = assembly.Place(objects.MARKER, marker_x, marker_y)
        return dataclasses.replace(config, places=(marker,))

    def _task_reset(self) -> None:
        super()._task_reset()
        self._in_bottle = self._offset = None

    def _task_info(self) -> dict[str, Any]:
        info = super()._task_info()
        in_bottle = self._fractions()[1]
        glass = self.data.body(objects.GLASS).xpos
        offset = float(np.hypot(*(glass[:2] - self._marker.xpos[:2])))
        if self._in_bottle is not None and in_bottle < self._in_bottle:  # liquid left it
            self._offset = max(self._offset or 0.0, offset)
        self._in_bottle = in_bottle
        info["marker_offset"] = offset if self._offset is None else self._offset
        info["is_success"] = info["is_success"] and over(info["marker_offset"])
        return info
