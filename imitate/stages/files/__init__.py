"""The run files the stages write and read, one class each.

- ``observations.npz``: :class:`ObservationsFile` (observe writes it; learn and figures read it)
- ``demos.npz``: :class:`DemosFile` (observe; learn, figures)
- ``model.npz``: :class:`ModelFile`, its :class:`Learned` part for planning (learn; optimize,
  replay, figures, the evaluation and the export)
- ``plan.npz``: :class:`PlanFile` with its :class:`Sweep` (optimize; replay, figures)
- ``replay.npz``: :class:`ReplayFile` with its :class:`Recording` (replay; figures)

``X.load(run_dir)`` reads a file, ``x.save(run_dir)`` writes it (atomically, see
:mod:`imitate.rundir.artifacts`; inside a stage, with its commit). A file's array names are
written in its own module only (beside those of the library's ``to_arrays``, which it holds:
``LearnedModel``'s, ``Plan``'s, ``Observations``'). A file that is missing or unusable raises
:class:`~imitate.errors.ImitateError` naming it and the command that writes it again.
"""

from imitate.stages.files.demos import DemosFile
from imitate.stages.files.model import Learned, ModelFile
from imitate.stages.files.observations import ObservationsFile
from imitate.stages.files.plan import PlanFile, Sweep
from imitate.stages.files.replay import Recording, ReplayFile

__all__ = [
    "DemosFile", "Learned", "ModelFile", "ObservationsFile", "PlanFile", "Recording", "ReplayFile",
    "Sweep",
]
