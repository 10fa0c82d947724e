"""``plan.npz``: the optimized movement and the Fig. 9 sweep over collision weights
(``optimize`` writes it)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from imitate.errors import ImitateError
from imitate.motion import Plan
from imitate.rundir.artifacts import save_npz
from imitate.rundir.layout import PLAN
from imitate.stages import table
from imitate.stages.files._npz import read, reading

__all__ = ["PlanFile", "Sweep"]


@dataclass(frozen=True, eq=False, repr=False)
class Sweep:
    """The movement optimized at each collision weight of the Fig. 9 sweep.

    Attributes:
        weights: ``(W,)`` collision weights, ascending.
        x: ``(W, T + 1, m)`` task state of each plan.
        q: ``(W, T + 1, n)`` joint positions of each plan [rad].
        clearance: ``(W, T + 1)`` smallest signed distance between the robot, the objects and
            the scene at each step of each plan [m], negative when penetrating.
        cost_total: One total cost per optimizer iteration of each plan.
    """

    weights: np.ndarray
    x: np.ndarray
    q: np.ndarray
    clearance: np.ndarray
    cost_total: tuple[np.ndarray, ...]

    def __repr__(self) -> str:
        return f"Sweep(weights {[float(w) for w in self.weights]}, q {self.q.shape})"


@dataclass(frozen=True, eq=False)
class PlanFile:
    """Contents of ``plan.npz``: the plan's arrays (:meth:`Plan.to_arrays`), ``sweep_weights``,
    ``sweep_x``, ``sweep_q``, ``sweep_clearance`` and ``sweep{i}_cost_total`` per weight ``i``.

    Attributes:
        plan: The movement at the run's collision weight.
        sweep: The sweep over collision weights.
    """

    plan: Plan
    sweep: Sweep

    def save(self, run_dir: Path) -> Path:
        """Write ``run_dir/plan.npz``, atomically (staged inside a stage)."""
        s = self.sweep
        return save_npz(Path(run_dir) / PLAN, {
            **self.plan.to_arrays(), "sweep_weights": s.weights, "sweep_x": s.x, "sweep_q": s.q,
            "sweep_clearance": s.clearance,
            **{f"sweep{i}_cost_total": cost for i, cost in enumerate(s.cost_total)},
        })

    @classmethod
    def load(cls, run_dir: Path) -> PlanFile:
        """Read ``run_dir/plan.npz``.

        Raises:
            ImitateError: it is missing or unusable, or holds NaN or inf where it drives the
                robot; the message names it and the stage to re-run.
        """
        names = ("sweep_weights", "sweep_x", "sweep_q", "sweep_clearance")
        a = read(run_dir, PLAN, (*Plan.array_names(), *names))
        costs = tuple(f"sweep{i}_cost_total" for i in range(len(a["sweep_weights"])))
        missing = [name for name in costs if name not in a]
        if missing:
            raise ImitateError(f"{a.path} lacks {missing}; {table.rerun(a.path)}")
        driven = (*Plan.array_names(), "sweep_q", "sweep_x")
        bad = [name for name in driven if name != "min_distance"  # inf: nothing within range
               and a[name].dtype.kind in "fc" and not np.isfinite(a[name]).all()]
        if bad:
            raise ImitateError(
                f"{a.path} holds NaN or inf in {', '.join(bad[:3])}"
                f"{' and more' if bad[3:] else ''}: a plan must be finite; {table.rerun(a.path)}"
            )
        with reading(a.path):
            sweep = Sweep(
                a["sweep_weights"], a["sweep_x"], a["sweep_q"], a["sweep_clearance"],
                tuple(a[name] for name in costs),
            )
            return cls(Plan.from_arrays(a), sweep)
