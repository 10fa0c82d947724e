"""A run directory as typed Python objects: :func:`load_run` -> :class:`Run`.

    run = imitate.load_run("runs/latest")
    mean, covariance = run.model.predict([0.0, 1.5])    # GMR at any time [s]
    run.plan.q, run.replay.pour_fraction, run.report["replay"]["success"]
    plan = run.replan(collision_weight=0.0)              # the learned model planned again

Each member reads its artifact the first time it is used (with :mod:`imitate.stages.files`); a
missing or corrupt artifact raises :class:`~imitate.errors.ImitateError` naming the file and the
stage to re-run.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from functools import cached_property
from pathlib import Path

import numpy as np

from imitate.demos.segment import task_demos
from imitate.envs.assembly import Obstacle, check_clearance
from imitate.envs.task import Task, get_task
from imitate.errors import ImitateError
from imitate.learning import LearnedModel
from imitate.motion import Plan
from imitate.motion.replay import reproduce
from imitate.perception import Observations
from imitate.rundir import layout
from imitate.rundir.schema import load_report
from imitate.stages.config import RunConfig, load_config
from imitate.stages.files import (
    DemosFile,
    Learned,
    ModelFile,
    ObservationsFile,
    PlanFile,
    Recording,
    ReplayFile,
)

__all__ = ["Run", "load_run"]


class Run:
    """A run directory (see :func:`load_run`); every member is read lazily, once.

    Attributes:
        path: The run directory.
    """

    def __init__(self, path: Path):
        self.path = Path(path)

    @cached_property
    def config(self) -> RunConfig:
        """The settings (``config.json``)."""
        return load_config(self.path)

    @cached_property
    def observations(self) -> Observations:
        """Tracks, camera matrices and ground truth (``observations.npz``)."""
        return ObservationsFile.load(self.path).observations

    @cached_property
    def demos(self) -> DemosFile:
        """The segmented demonstrations (``demos.npz``)."""
        return DemosFile.load(self.path)

    @property
    def task(self) -> Task:
        """The run's task in the space its model was learned in (:meth:`Learned.task`)."""
        return self.learned.task(get_task(self.config.task))

    def task_demos(self) -> tuple[list[np.ndarray], float]:
        """The demonstrations in the task's space as the ``learn`` stage projects them (one
        ``(n_i, m)`` array each, in :attr:`gaze`'s frame) and their rate [Hz]: the arrays
        :func:`imitate.learn` takes."""
        d = self.demos
        return task_demos(d.segments, d.objects, d.gaze, self.task.space,
                          smoothing=self.config.smoothing)

    @cached_property
    def learned(self) -> Learned:
        """The learned model and its gaze frame (``model.npz``)."""
        return ModelFile.load_learned(self.path)

    @property
    def model(self) -> LearnedModel:
        """The learned model (``model.npz``): GMM, BIC curve, GMR mean and covariance at its
        ``times``, and :meth:`~imitate.learning.LearnedModel.predict` at any time; of a
        ``--task-space tpgmm`` run, in TP-GMM's frames (``learned.planned`` is what plans
        reproduce, in :attr:`task`'s space)."""
        return self.learned.model

    @property
    def gaze(self) -> np.ndarray:
        """``(3, 3)`` gaze frame the model's task space is expressed in (``model.npz``)."""
        return self.learned.gaze

    @cached_property
    def plan(self) -> Plan:
        """The optimized movement (``plan.npz``): ``q(t)``, ``x(t)``, attractors, costs."""
        return PlanFile.load(self.path).plan

    @cached_property
    def replay(self) -> Recording:
        """The replay in physics (``replay.npz``)."""
        return ReplayFile.load(self.path).recording

    @cached_property
    def report(self) -> dict:
        """``report.json``: its keys are declared in :mod:`imitate.rundir.schema`."""
        return load_report(self.path / layout.REPORT)

    def replan(self, *, obstacles: Sequence[Obstacle] | None = None, **settings) -> Plan:
        """The learned model planned again as the ``optimize`` stage plans it, with
        ``settings`` replaced; nothing written.

        Args:
            obstacles: Obstacles on the table instead of the run's (``()`` for none).
            **settings: Fields of :class:`~imitate.motion.PlanConfig` (``collision_weight``,
                ``similarity``, ``sigma_max_scale``, ``max_iter``, ...) instead of the run's.

        Raises:
            ImitateError: an unknown setting, a bad value, or an obstacle that overlaps the
                robot or what it holds.
        """
        scene = self.config.scene(task=self.task)
        if obstacles is not None:
            scene = dataclasses.replace(scene, obstacles=tuple(obstacles))
            check_clearance(scene)
        return reproduce(
            self.learned.planned, gaze=self.gaze, scene=scene, config=self.config.plan_config(),
            **settings,
        )

    def __repr__(self) -> str:
        return f"Run({str(self.path)!r})"


def load_run(path: str | Path) -> Run:
    """The run in directory ``path`` (written by ``imitate run --out PATH``).

    Raises:
        ImitateError: ``path`` is not a directory.
    """
    path = Path(path)
    if not path.is_dir():
        raise ImitateError(
            f"run directory {path} not found; accepted: a directory written by "
            f"`imitate run --out {path}`"
        )
    return Run(path)
