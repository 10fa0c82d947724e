"""``model.npz``: the learned model, its gaze frame and what the figures show of learning
(``learn`` writes it)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imitate.envs.task import Task
from imitate.learning import LearnedModel, tpgmm
from imitate.rundir.artifacts import save_npz
from imitate.rundir.layout import MODEL
from imitate.stages.files._npz import read, reading
from imitate.taskspace import TaskSpace

__all__ = ["Learned", "ModelFile"]

RAW = "raw_"  # the prefix of the model learned without DTW


@dataclass(frozen=True, eq=False)
class Learned:
    """A learned model in its task space's frame: what planning needs of ``model.npz``.

    Attributes:
        model: The model (GMM and GMR, learned with DTW).
        gaze: ``(3, 3)`` gaze frame its task space is expressed in.
        importance: ``(m, m)`` the task's measured importance in the critical phase (tolerance
            units, :mod:`imitate.evaluation.sensitivity`), which the ``importance`` weighting
            plans with; ``None`` where not measured (not in ``model.npz``).
        space: The task space it was learned in where the run chose it (``--task-space auto``
            or ``tpgmm``, ``model.npz``'s ``task_space``); ``None``: the task's declared one.
        frames: Whether ``space`` holds TP-GMM's candidate frames (``--task-space tpgmm``,
            ``model.npz``'s ``frames``): plans reproduce it by their product in each scene.
    """

    model: LearnedModel
    gaze: np.ndarray
    importance: np.ndarray | None = None
    space: TaskSpace | None = None
    frames: bool = False

    def task(self, task: Task) -> Task:
        """``task`` in the space this model is planned in (``task`` itself where that is its
        declared one; TP-GMM's reproduction space for frames)."""
        if self.frames:
            assert self.space is not None  # frames are stored with their space
            return task.in_space(tpgmm.reproduction_space(self.space.places))
        return task if self.space is None else task.in_space(self.space)

    @property
    def planned(self) -> LearnedModel | tpgmm.FrameModel:
        """What a plan reproduces: the model, or in frames the :class:`~imitate.learning.tpgmm.
        FrameModel` the planner reproduces at each scene's places."""
        if self.frames:
            assert self.space is not None  # frames are stored with their space
            return tpgmm.FrameModel(self.model, self.space)
        return self.model


@dataclass(frozen=True, eq=False)
class ModelFile:
    """Contents of ``model.npz``: the model's arrays (:meth:`LearnedModel.to_arrays`), those of
    the model learned without DTW (prefixed ``raw_``), ``gaze``, ``rate``, ``bic_fast``,
    ``bic_full``, ``aligned`` and, where the run chose its space, ``task_space`` (its terms as
    text, :attr:`TaskSpace.text`) and, in TP-GMM's frames, ``frames``.

    Attributes:
        learned: The model learned with DTW and its gaze frame.
        raw: The model learned without DTW, with as many components (Fig. 4).
        rate: Rate of the demonstrations it was learned from [Hz].
        bic_fast: ``(k_max,)`` BIC of each number of components, by the fast K-means heuristic
            (Fig. 5).
        bic_full: ``(k_max,)`` the same by the full BIC (EM for every K).
        aligned: ``(n_demos, T, m)`` the demonstrations after DTW, in the task space.
    """

    learned: Learned
    raw: LearnedModel
    rate: float
    bic_fast: np.ndarray
    bic_full: np.ndarray
    aligned: np.ndarray

    def save(self, run_dir: Path) -> Path:
        """Write ``run_dir/model.npz``, atomically (staged inside a stage)."""
        return save_npz(Path(run_dir) / MODEL, {
            **self.learned.model.to_arrays(), **self.raw.to_arrays(RAW),
            "gaze": self.learned.gaze, "rate": self.rate, "bic_fast": self.bic_fast,
            "bic_full": self.bic_full, "aligned": self.aligned,
            **({} if self.learned.space is None
               else {"task_space": np.array(self.learned.space.text)}),
            **({"frames": np.array(True)} if self.learned.frames else {}),
        })

    @classmethod
    def load(cls, run_dir: Path) -> ModelFile:
        """Read ``run_dir/model.npz``, all of it.

        Raises:
            ImitateError: it is missing or unusable (an array missing, not finite, or of
                shapes that disagree); the message names it and the stage to re-run.
        """
        a = read(run_dir, MODEL, (
            *LearnedModel.array_names(), *LearnedModel.array_names(RAW), "gaze", "rate",
            "bic_fast", "bic_full", "aligned",
        ))
        with reading(a.path):
            return cls(
                Learned(LearnedModel.from_arrays(a), a["gaze"], space=_space(a),
                        frames=_frames(a)),
                raw=LearnedModel.from_arrays(a, RAW), rate=float(a["rate"]),
                bic_fast=a["bic_fast"], bic_full=a["bic_full"], aligned=a["aligned"],
            )

    @staticmethod
    def load_learned(run_dir: Path) -> Learned:
        """Read the learned model and its gaze frame of ``run_dir/model.npz`` (the other arrays
        are neither read nor needed), as :meth:`load` does."""
        a = read(run_dir, MODEL, (*LearnedModel.array_names(), "gaze"))
        with reading(a.path):
            return Learned(LearnedModel.from_arrays(a), a["gaze"], space=_space(a),
                           frames=_frames(a))


def _frames(arrays: Mapping[str, np.ndarray]) -> bool:
    """Whether ``model.npz``'s arrays hold a model in TP-GMM's frames (``frames``)."""
    return "frames" in arrays and bool(arrays["frames"])


def _space(arrays: Mapping[str, np.ndarray]) -> TaskSpace | None:
    """The space ``model.npz``'s arrays name (``task_space``), ``None`` where they name none."""
    return TaskSpace.from_text(arrays["task_space"].tolist()) if "task_space" in arrays else None
