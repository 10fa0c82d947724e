"""``demos.npz``: the demonstrations cut from the tracks (``observe`` writes it)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imitate.demos.segment import Demonstration
from imitate.errors import ImitateError
from imitate.rundir.artifacts import save_npz
from imitate.rundir.layout import DEMOS
from imitate.stages import table
from imitate.stages.files._npz import read

__all__ = ["DemosFile"]

_FIELDS = ("times", "position", "axis", "angle")  # a demonstration's arrays, demo{i}_<field>


@dataclass(frozen=True, eq=False, repr=False)
class DemosFile:
    """Contents of ``demos.npz``: ``objects``, ``gaze``, ``boundaries`` and, per demonstration
    ``i``, ``demo{i}_times``, ``demo{i}_position``, ``demo{i}_axis`` and ``demo{i}_angle``.

    Attributes:
        segments: One :class:`~imitate.demos.segment.Demonstration` per demonstration, in time
            order.
        objects: Object names, the first axis of each segment's arrays.
        gaze: ``(3, 3)`` gaze frame of the observation (columns right, down, forward).
    """

    segments: tuple[Demonstration, ...]
    objects: tuple[str, ...]
    gaze: np.ndarray

    @property
    def boundaries(self) -> np.ndarray:
        """``(n_demos, 2)`` start and end of each demonstration [s]."""
        return np.array([(d.start, d.end) for d in self.segments])

    def save(self, run_dir: Path) -> Path:
        """Write ``run_dir/demos.npz``, atomically (staged inside a stage)."""
        arrays = {
            "objects": np.array(self.objects), "gaze": self.gaze, "boundaries": self.boundaries,
        }
        for i, demo in enumerate(self.segments):
            for name in _FIELDS:
                arrays[f"demo{i}_{name}"] = getattr(demo, name)
        return save_npz(Path(run_dir) / DEMOS, arrays)

    @classmethod
    def load(cls, run_dir: Path) -> DemosFile:
        """Read ``run_dir/demos.npz``.

        Raises:
            ImitateError: it is missing or unusable; the message names it and the stage to
                re-run.
        """
        a = read(run_dir, DEMOS, ("objects", "gaze", "boundaries"))
        segments = []
        for i, (start, end) in enumerate(a["boundaries"]):
            names = [f"demo{i}_{name}" for name in _FIELDS]
            if not all(name in a for name in names):
                raise ImitateError(
                    f"{a.path} lacks the arrays of demonstration {i}; {table.rerun(a.path)}"
                )
            fields = dict(zip(_FIELDS, (a[name] for name in names), strict=True))
            segments.append(Demonstration(float(start), float(end), **fields))
        return cls(tuple(segments), tuple(str(name) for name in a["objects"]), a["gaze"])

    def __repr__(self) -> str:
        return f"Demos({len(self.segments)} demonstrations of {', '.join(self.objects)})"
