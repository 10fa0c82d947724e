"""``observations.npz``: what the robot saw (``observe`` writes it)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from imitate.perception import Observations
from imitate.rundir.artifacts import save_npz
from imitate.rundir.layout import OBSERVATIONS
from imitate.stages.files._npz import read, reading

__all__ = ["ObservationsFile"]


@dataclass(frozen=True, eq=False)
class ObservationsFile:
    """Contents of ``observations.npz`` (its arrays: :meth:`Observations.to_arrays`).

    Attributes:
        observations: The tracks, the cameras and the ground truth.
    """

    observations: Observations

    def save(self, run_dir: Path) -> Path:
        """Write ``run_dir/observations.npz``, atomically (staged inside a stage)."""
        return save_npz(Path(run_dir) / OBSERVATIONS, self.observations.to_arrays())

    @classmethod
    def load(cls, run_dir: Path) -> ObservationsFile:
        """Read ``run_dir/observations.npz``.

        Raises:
            ImitateError: it is missing or unusable; the message names it and the stage to
                re-run.
        """
        arrays = read(run_dir, OBSERVATIONS, Observations.array_names())
        with reading(arrays.path):
            return cls(Observations.from_arrays(arrays))
