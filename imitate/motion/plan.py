"""The optimized movement (:class:`Plan`) and its storage as named arrays (``plan.npz``)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["Plan"]


@dataclass(frozen=True, repr=False)
class Plan:
    """Result of :func:`imitate.motion.plan_from_model`.

    Attributes:
        times: ``(T + 1,)`` [s].
        attractors: ``(K, m)`` optimized attractor points, sorted by time.
        push: ``(K, n)`` null-space push of each attractor [1/rad] (see
            :class:`imitate.motion.PlanConfig`'s ``nullspace_push``); zeros when unused.
        target: ``(T + 1, m)`` attractor trajectory ``x_t`` (what RMR tracks).
        x: ``(T + 1, m)`` task state reached, ``phi(q_t)``.
        q: ``(T + 1, n)`` joint angles [rad] in ``Kinematics.joints`` order.
        q_start: ``(n,)`` start posture (``q[0]``), reached from the given posture by RMR.
        approach_bend: ``(n,)`` bend [rad] of the joint-space path from the given posture to
            ``q_start`` (:mod:`imitate.motion.approach`); zeros for the straight line.
        mean, variance, weights: GMR mean, variance and eq. 21 weights at ``times``, ``(T+1, m)``.
        covariance: GMR covariance at ``times``, ``(T + 1, m, m)``.
        costs: ``{term: (n_iter + 1,)}`` weighted cost per iteration of the accepted iterate,
            and ``"total"``.
        min_distance: Smallest signed distance [m] over the approach and the
            trajectory (its steps and the samples along the straight lines between them) and
            all pairs.
        closest: Geom names of that pair (``None`` if none is within 0.2 m).
        converged: Whether the stopping rule was met within ``max_iter``.
        clipped: Joint-angle clips in the best rollout.
        message: What happened, in words (convergence, collisions, unreachable targets).
        n_iter: Iterations run.
        n_evaluations: Rollouts evaluated.
    """

    times: np.ndarray
    attractors: np.ndarray
    push: np.ndarray
    target: np.ndarray
    x: np.ndarray
    q: np.ndarray
    q_start: np.ndarray
    approach_bend: np.ndarray
    mean: np.ndarray
    variance: np.ndarray
    covariance: np.ndarray
    weights: np.ndarray
    costs: dict[str, np.ndarray]
    min_distance: float
    closest: tuple[str, str] | None
    converged: bool
    clipped: int
    message: str
    n_iter: int
    n_evaluations: int

    def __repr__(self) -> str:
        done = "converged" if self.converged else "not converged"
        return (
            f"Plan({len(self.times)} steps over {self.times[0]:g}..{self.times[-1]:.3g} s, "
            f"q {self.q.shape}, x {self.x.shape}, {len(self.attractors)} attractors, {done} "
            f"after {self.n_iter} iterations, min_distance {1e3 * self.min_distance:.1f} mm, "
            f"costs {sorted(self.costs)})"
        )

    def task_error(self) -> np.ndarray:
        """``(T + 1, m)`` reached minus learned, ``phi(q_t) - mu_t``."""
        return self.x - self.mean

    @staticmethod
    def array_names() -> tuple[str, ...]:
        """Names of the arrays :meth:`to_arrays` always writes (besides ``cost_<term>``)."""
        return tuple(f.name for f in dataclasses.fields(Plan) if f.name != "costs")

    def to_arrays(self) -> dict[str, np.ndarray]:
        """The plan as named arrays (for ``plan.npz``): one per field, scalars 0-d, ``closest``
        as strings (empty for ``None``), and ``cost_<term>`` per cost term."""
        arrays = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == "costs":
                arrays.update({f"cost_{term}": v for term, v in value.items()})
            elif f.name == "closest":
                arrays[f.name] = np.array(value or (), dtype=str)
            else:
                arrays[f.name] = np.asarray(value)
        return arrays

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, np.ndarray]) -> Plan:
        """The plan stored by :meth:`to_arrays`; other arrays in ``arrays`` are ignored."""
        values: dict[str, Any] = {
            name: arrays[name] if arrays[name].ndim else arrays[name].item()
            for name in cls.array_names()
        }
        values["closest"] = tuple(str(n) for n in arrays["closest"]) or None
        values["message"] = str(arrays["message"])
        values["costs"] = {
            k.removeprefix("cost_"): v for k, v in arrays.items() if k.startswith("cost_")
        }
        return cls(**values)
