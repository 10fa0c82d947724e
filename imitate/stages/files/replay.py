"""``replay.npz``: the plan replayed in physics, and the sweep's weight-0 plan replayed
(``replay`` writes it)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from imitate.rundir.artifacts import save_npz
from imitate.rundir.layout import REPLAY
from imitate.stages.files._npz import read, reading

__all__ = ["FREE", "STATES", "Recording", "ReplayFile"]

STATES = ("qpos", "mocap_pos", "mocap_quat")  # a recorded state (envs.video.StateRecorder)
FREE = "sweep0_"  # the prefix of the weight-0 plan's recorded states
_OWN = ("task_error", "state_dt", "min_distance", "plan_start")  # a recording's besides STATES


@dataclass(frozen=True, eq=False, repr=False)
class Recording:
    """The plan replayed in physics: its states, recorded to be rendered again, and its numbers.

    Attributes:
        qpos: ``(n, nq)`` MuJoCo ``qpos`` of the whole scene every ``state_dt`` [rad, m].
        mocap_pos: ``(n, n_mocap, 3)`` the teacher's mocap positions [m].
        mocap_quat: ``(n, n_mocap, 4)`` their orientations, wxyz.
        state_dt: Time between recorded states [s].
        plan_start: When the plan starts, after the approach from the reset pose [s].
        task_error: ``(T, m)`` task state reached in physics minus the plan's, every env step of
            the plan's part.
        min_distance: Smallest signed distance [m] between geoms that must not touch.
        measures: The task's numbers of the replay by name (a fraction, a count...); each is
            also an attribute (``recording.<name>``).
    """

    qpos: np.ndarray
    mocap_pos: np.ndarray
    mocap_quat: np.ndarray
    state_dt: float
    plan_start: float
    task_error: np.ndarray
    min_distance: float
    measures: dict[str, float] = field(default_factory=dict)

    @property
    def times(self) -> np.ndarray:
        """``(n,)`` times of the recorded states [s] from the reset."""
        return np.arange(len(self.qpos)) * self.state_dt

    def states(self) -> dict[str, np.ndarray]:
        """The recorded states by name (:data:`STATES`), as ``StateRecorder.arrays()``."""
        return {name: getattr(self, name) for name in STATES}

    def __getattr__(self, name: str) -> float:
        measures = self.__dict__.get("measures", {})
        if name in measures:
            return measures[name]
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    def __repr__(self) -> str:
        numbers = ", ".join(f"{name} {value:.3g}" for name, value in self.measures.items())
        return (
            f"Recording({len(self.qpos)} states every {self.state_dt:g} s, qpos "
            f"{self.qpos.shape}, {numbers}, min_distance {1e3 * self.min_distance:.1f} mm)"
        )


@dataclass(frozen=True, eq=False)
class ReplayFile:
    """Contents of ``replay.npz``: the recording's states (:data:`STATES`), ``task_error``,
    ``state_dt``, its measures (one array each, by name), ``min_distance``, ``plan_start``, and
    the weight-0 plan's states (prefixed ``sweep0_``).

    Attributes:
        recording: The plan replayed.
        free: The states of the sweep's smallest collision weight's plan replayed (Fig. 8's top
            row), by name, recorded as ``recording``'s (same spacing and start).
    """

    recording: Recording
    free: dict[str, np.ndarray]

    def save(self, run_dir: Path) -> Path:
        """Write ``run_dir/replay.npz``, atomically (staged inside a stage)."""
        r = self.recording
        return save_npz(Path(run_dir) / REPLAY, {
            **r.states(), "task_error": r.task_error, "state_dt": r.state_dt, **r.measures,
            "min_distance": r.min_distance, "plan_start": r.plan_start,
            **{FREE + name: self.free[name] for name in STATES},
        })

    @classmethod
    def load(cls, run_dir: Path) -> ReplayFile:
        """Read ``run_dir/replay.npz``; its measures are its other 0-d arrays.

        Raises:
            ImitateError: it is missing or unusable; the message names it and the stage to
                re-run.
        """
        free = tuple(FREE + name for name in STATES)
        a = read(run_dir, REPLAY, (*STATES, *_OWN, *free))
        with reading(a.path):
            measures = {
                name: value.item() for name, value in a.items()
                if name not in (*STATES, *_OWN, *free) and value.ndim == 0
            }
            recording = Recording(
                qpos=a["qpos"], mocap_pos=a["mocap_pos"], mocap_quat=a["mocap_quat"],
                state_dt=float(a["state_dt"]), plan_start=float(a["plan_start"]),
                task_error=a["task_error"], min_distance=float(a["min_distance"]),
                measures=measures,
            )
            return cls(recording, {name: a[FREE + name] for name in STATES})
