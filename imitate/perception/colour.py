"""What the robot knows about the objects: their colour ranges and shapes.

:func:`object_models` derives them from the scene's objects (:mod:`imitate.models.shapes`, by
name): a hue range around each one's colour, and its outer profile.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np

from imitate.errors import ImitateError
from imitate.models import shapes


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
        # cv2's stubs type inRange's uint8 mask as an integer or floating array.
        return cv2.inRange(hsv, lo, top) | cv2.inRange(hsv, bottom, hi)  # type: ignore[operator]


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


def colour_range(rgba, hue_tolerance: int = 12) -> ColourRange:
    """HSV range of a uniformly coloured, shaded surface of colour ``rgba``.

    Hue within ``hue_tolerance`` (OpenCV half-degrees) of the colour's, saturation from 100
    (shading keeps it; the grey and skin of the scene stay below), any value from 30.
    """
    pixel = np.uint8(np.round(np.array(rgba[:3]) * 255))[None, None]
    hue = int(cv2.cvtColor(pixel, cv2.COLOR_RGB2HSV)[0, 0, 0])
    return ColourRange(
        ((hue - hue_tolerance) % 180, 100, 30), ((hue + hue_tolerance) % 180, 255, 255)
    )


def object_models(names: Sequence[str]) -> tuple[ObjectModel, ...]:
    """The objects ``names`` (of :data:`imitate.models.shapes.SHAPES`, e.g. a task's tool and
    target) as the robot knows them: colour range and outer radius profile.

    Raises:
        ImitateError: a name of no object.
    """
    unknown = [name for name in names if name not in shapes.SHAPES]
    if unknown:
        raise ImitateError(f"objects {unknown} unknown; accepted: {list(shapes.SHAPES)}")
    return tuple(
        ObjectModel(
            name=name,
            colour=colour_range(shape.rgba),
            profile=tuple((r + shape.wall / 2, h) for r, h in shape.profile),
        )
        for name, shape in ((name, shapes.SHAPES[name]) for name in names)
    )
