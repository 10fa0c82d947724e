"""A run directory as typed Python objects: :func:`load_run` -> :class:`Run`.

    run = imitate.load_run("runs/latest")
    mean, covariance = run.model.predict([0.0, 1.5])    # GMR at any time [s]
    run.plan.q, run.replay.pour_fraction, run.report["replay"]["success"]
    plan = run.replan(collision_weight=0.0)              # the learned model planned again

Each member reads its artifact the first time it is used; a missing or corrupt artifact raises
:class:`~imitate.errors.ImitateError` naming the file and the stage to re-run.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from imitate.demos.segment import Demonstration, load_demos, task_demos
from imitate.envs.assembly import Obstacle, check_clearance
from imitate.errors import ImitateError
from imitate.learning import LearnedModel
from imitate.motion import Plan
from imitate.motion.replay import reproduce
from imitate.perception import Observations, load_observations
from imitate.rundir import table
from imitate.rundir.artifacts import load_json, load_npz
from imitate.rundir.schema import check_schema
from imitate.stages.config import RunConfig, load_config

__all__ = ["Demos", "Recording", "Run", "load_run"]


@dataclass(frozen=True, eq=False, repr=False)
class Demos:
    """Contents of ``demos.npz``: the demonstrations cut from the tracks.

    Attributes:
        segments: One :class:`~imitate.demos.segment.Demonstration` per demonstration, in time
            order.
        objects: Object names, the first axis of each segment's arrays.
        gaze: ``(3, 3)`` gaze frame of the observation (columns right, down, forward).
    """

    segments: tuple[Demonstration, ...]
    objects: tuple[str, ...]
    gaze: np.ndarray

    def __repr__(self) -> str:
        return f"Demos({len(self.segments)} demonstrations of {', '.join(self.objects)})"


@dataclass(frozen=True, eq=False, repr=False)
class Recording:
    """Contents of ``replay.npz``: the plan replayed in physics.

    Attributes:
        qpos: ``(n, nq)`` MuJoCo ``qpos`` of the whole scene every ``state_dt`` [rad, m].
        mocap_pos: ``(n, n_mocap, 3)`` the teacher's mocap positions [m].
        mocap_quat: ``(n, n_mocap, 4)`` their orientations, wxyz.
        state_dt: Time between recorded states [s].
        task_error: ``(T, 7)`` task state reached in physics minus the plan's, every env step of
            the plan's part.
        pour_fraction: Fraction of the particles in the glass at the end.
        spilled: Particles in neither container at the end.
        min_distance: Smallest signed distance [m] between geoms that must not touch.
    """

    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    state_dt: float
    task_error: np.ndarray
    pour_fraction: float
    spilled: int
    min_distance: float

    @property
    def times(self) -> np.ndarray:
        """``(n,)`` times of the recorded states [s] from the reset."""
        return np.arange(len(self.qpos)) * self.state_dt

    def __repr__(self) -> str:
        return (
            f"Recording({len(self.qpos)} states every {self.state_dt:g} s, qpos "
            f"{self.qpos.shape}, pour_fraction {self.pour_fraction:.3g}, spilled {self.spilled}, "
            f"min_distance {1e3 * self.min_distance:.1f} mm)"
        )


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
        return load_observations(self.path / "observations.npz")

    @cached_property
    def demos(self) -> Demos:
        """The segmented demonstrations (``demos.npz``)."""
        segments, objects, gaze = load_demos(self.path / "demos.npz")
        return Demos(tuple(segments), objects, gaze)

    def task_demos(self) -> tuple[list[np.ndarray], float]:
        """The demonstrations in eq. 1's task space as the ``learn`` stage projects them (one
        ``(n_i, 7)`` array each, in :attr:`gaze`'s frame) and their rate [Hz]: the arrays
        :func:`imitate.learn` takes."""
        d = self.demos
        return task_demos(d.segments, d.objects, d.gaze, smoothing=self.config.smoothing)

    @cached_property
    def model(self) -> LearnedModel:
        """The learned model (``model.npz``): GMM, BIC curve, GMR mean and covariance at its
        ``times``, and :meth:`~imitate.learning.LearnedModel.predict` at any time."""
        path = self.path / "model.npz"
        return LearnedModel.from_arrays(load_npz(path, required=LearnedModel.array_names()))

    @cached_property
    def gaze(self) -> np.ndarray:
        """``(3, 3)`` gaze frame the model's task space is expressed in (``model.npz``)."""
        return load_npz(self.path / "model.npz", required=("gaze",))["gaze"]

    @cached_property
    def plan(self) -> Plan:
        """The optimized movement (``plan.npz``): ``q(t)``, ``x(t)``, attractors, costs."""
        return Plan.from_arrays(load_npz(self.path / "plan.npz", required=Plan.array_names()))

    @cached_property
    def replay(self) -> Recording:
        """The replay in physics (``replay.npz``)."""
        a = load_npz(self.path / "replay.npz", required=_RECORDING)
        return Recording(
            qpos=a["qpos"], mocap_pos=a["mocap_pos"], mocap_quat=a["mocap_quat"],
            state_dt=float(a["state_dt"]), task_error=a["task_error"],
            pour_fraction=float(a["pour_fraction"]), spilled=int(a["spilled"]),
            min_distance=float(a["min_distance"]),
        )

    @cached_property
    def report(self) -> dict:
        """``report.json``: its keys are declared in :mod:`imitate.rundir.schema`."""
        path = self.path / table.REPORT
        return check_schema(load_json(path), path)

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
        scene = self.config.scene()
        if obstacles is not None:
            scene = dataclasses.replace(scene, obstacles=tuple(obstacles))
            check_clearance(scene)
        return reproduce(
            self.model, gaze=self.gaze, scene=scene, config=self.config.plan_config(), **settings
        )

    def __repr__(self) -> str:
        return f"Run({str(self.path)!r})"


_RECORDING = (
    "qpos", "mocap_pos", "mocap_quat", "state_dt", "task_error", "pour_fraction", "spilled",
    "min_distance",
)


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
