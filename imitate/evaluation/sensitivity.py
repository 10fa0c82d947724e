"""The task's measured tolerance: how far a teacher's reproduction may be moved in the critical
phase, direction by direction, before the task fails in physics; and whether the demonstrations'
agreement points at the same directions (the premise of eq. 21, measured instead of assumed).

For one teacher, its reproduction in the task's default scene (default settings, eq. 21) is moved
through the critical phase (``Task.critical``, eased in and out over :data:`RAMP`) by ``k``
tolerances (the task space's per dimension: 1 cm, 2 deg, 0.05) along
:func:`probe_directions`: each task dimension, then each eigen-direction of the demonstrations'
covariance there. The move is the joints' least-norm change ``J^+ delta`` at every step
(:func:`moved`). Each moved plan is replayed in physics from ``seeds`` seeds; a replay fails
where the task's score is below its threshold or the physics diverged. A direction's
**tolerance** is the smallest move, either way, at which half the replays fail (interpolated
between magnitudes; ``inf`` if none does); its **importance** is ``1 / tolerance^2``, the
stiffness of a quadratic loss that reaches 1 there. The m x m quadratic form ``Q`` (tolerance
units) holding these importances is fitted by non-negative least squares over the probed
directions' rank-one forms (:func:`quadratic_form`): for eq. 1, 14 directions fix 14 of its 28
numbers.

A teacher's result is kept in ``RUN_DIR/sensitivity/seed-S.json`` (:func:`result_path`, written
by ``imitate sensitivity``, :mod:`~imitate.evaluation.sensitivity_run`); :func:`with_importance`
gives the teachers the form ``Q + I / k^2`` (``k`` the largest move probed: a direction no move
failed keeps the importance of that move) for the ``importance`` weighting
(:func:`~imitate.motion.costs.weighting`).

The **alignment** of a teacher is the rank correlation between the demonstrations' precision
(inverse variance, tolerance units) and the measured importance over the covariance's
eigen-directions, and in diagonal form over the task dimensions (7 for eq. 1): eq. 21 assumes it
is high.
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from scipy.optimize import nnls
from scipy.stats import spearmanr

from imitate.envs.task import Task
from imitate.errors import ImitateError
from imitate.evaluation.teachers import Teacher
from imitate.learning import LearnedModel
from imitate.models import humanoid
from imitate.motion import Plan, PlanConfig, plan_from_model
from imitate.motion.replay import measure, planning_task
from imitate.motion.taskspace import TaskMap
from imitate.rundir.artifacts import load_json

__all__ = [
    "MAGNITUDES", "RAMP", "SEEDS", "alignment", "critical_covariance", "direction_names",
    "failure_rates", "model_digest", "moved", "probe_directions", "quadratic_form",
    "reproduction", "result_path", "results_folder", "tolerance", "window", "with_importance",
]

MAGNITUDES = (1.0, 2.0, 4.0)  # moves [tolerances], each way
SEEDS = 3  # replays of each moved plan, seeds 0, 1, 2
RAMP = 0.4  # [s] over which a move eases in before the critical phase and out after it
_DAMPING = 1e-8  # of J J^T in the least-norm joint change


def direction_names(task: Task) -> tuple[str, ...]:
    """The probed directions' names: the task dimensions, then the covariance's eigenvectors,
    the most agreed first."""
    return (*task.dims, *(f"eigen {i + 1}" for i in range(len(task.dims))))


def reproduction(learned: LearnedModel, gaze: np.ndarray, task: Task) -> Plan:
    """The teacher's reproduction in ``task``'s default scene with the default settings (the
    plan its default run replays)."""
    return plan_from_model(
        planning_task(task.scene(), gaze), learned, q0=humanoid.rest_pose(),
        config=PlanConfig(), critical=task.critical,
    )


def critical_covariance(learned: LearnedModel, plan: Plan, task: Task) -> np.ndarray:
    """The GMR covariance averaged over ``task``'s critical steps of ``plan``, in tolerance
    units (``D^-1 Sigma D^-1``, ``D = diag(tolerance)`` of its space), ``(m, m)``."""
    covariance = learned.predict(plan.times[task.critical(plan.mean)])[1].mean(axis=0)
    scale = 1.0 / task.space.tolerance
    return covariance * np.outer(scale, scale)


def probe_directions(covariance: np.ndarray) -> np.ndarray:
    """``(2 m, m)`` unit directions in tolerance units: the m task dimensions, then the
    eigenvectors of ``covariance`` ``(m, m)`` (tolerance units), the most agreed first, each
    with its largest component positive."""
    vectors = np.linalg.eigh(covariance)[1].T  # rows, ascending eigenvalues
    largest = vectors[np.arange(len(vectors)), np.abs(vectors).argmax(axis=1)]
    return np.vstack([np.eye(len(vectors)), vectors * np.sign(largest)[:, None]])


def moved(plan: Plan, task_map: TaskMap, delta: np.ndarray, window: np.ndarray) -> Plan:
    """``plan`` with its joints moved by ``window_t J_t^+ delta`` at every step: the task
    state moved by ``delta`` ``(m,)`` (task units) to first order where ``window`` ``(T + 1,)``
    is 1. ``task_map``'s kinematics are left at the plan's last step."""
    q = plan.q.copy()
    for t in np.flatnonzero(window):
        task_map.kin.update(plan.q[t])
        _, J = task_map(task_map.space.angle_ref(plan.x[t]))
        q[t] += window[t] * J.T @ np.linalg.solve(J @ J.T + _DAMPING * np.eye(len(J)), delta)
    return dataclasses.replace(plan, q=q)


def window(times: np.ndarray, critical: np.ndarray, ramp: float = RAMP) -> np.ndarray:
    """``(T + 1,)`` 1 on the ``critical`` steps, easing to 0 (a half cosine) over ``ramp`` [s]
    before and after them, 0 elsewhere."""
    inside = times[critical]
    gap = np.maximum(inside.min() - times, times - inside.max()).clip(0.0)
    return np.where(critical, 1.0, 0.5 + 0.5 * np.cos(np.pi * np.minimum(gap / ramp, 1.0)))


def failure_rates(
    plan: Plan, task_map: TaskMap, task: Task, gaze: np.ndarray, direction: np.ndarray,
    magnitudes: Sequence[float] = MAGNITUDES, seeds: int = SEEDS,
) -> np.ndarray:
    """``(2, len(magnitudes))`` the share of failed replays of ``plan`` moved by ``-k`` (row 0)
    and ``+k`` (row 1) tolerances along ``direction`` ``(m,)`` (tolerance units) in the critical
    phase, each from ``seeds`` seeds, in the task's default scene; ``magnitudes`` ascending. A
    magnitude past one at which every replay failed is taken as failing, not replayed."""
    critical = task.critical(plan.mean)
    ease = window(plan.times, critical)
    rates = np.zeros((2, len(magnitudes)))
    for side, sign in enumerate((-1.0, 1.0)):
        for i, k in enumerate(magnitudes):
            if i and rates[side, i - 1] == 1.0:  # every replay failed: a larger move fails too
                rates[side, i] = 1.0
                continue
            probe = moved(plan, task_map, sign * k * direction * task.space.tolerance, ease)
            failed = 0
            for seed in range(seeds):
                _, record, _ = measure(task, probe, task.make_env(task.scene()), seed=seed,
                                       gaze=gaze, options={})
                failed += record["diverged"] or record[task.score.measure] < task.score.threshold
            rates[side, i] = failed / seeds
    return rates


def tolerance(rates: np.ndarray, magnitudes: Sequence[float] = MAGNITUDES) -> float:
    """The smallest move [tolerances] at which half the replays fail, either way, of
    :func:`failure_rates`' ``(2, k)``: linear between the magnitudes (and 0 failing at 0);
    ``inf`` if no magnitude fails half."""
    grid = np.concatenate([[0.0], magnitudes])
    found = []
    for side in rates:
        curve = np.concatenate([[0.0], side])
        above = np.flatnonzero(curve >= 0.5)
        if above.size:
            i = above[0]
            found.append(np.interp(0.5, curve[i - 1 : i + 1], grid[i - 1 : i + 1]))
    return float(min(found, default=np.inf))


def quadratic_form(directions: np.ndarray, importance: np.ndarray) -> np.ndarray:
    """``Q`` ``(m, m)``, positive semi-definite, with ``u_i^T Q u_i`` nearest to
    ``importance`` ``(k,)`` over ``directions`` ``(k, m)`` (unit, tolerance units):
    ``Q = sum_i c_i u_i u_i^T``, ``c >= 0`` by non-negative least squares."""
    design = (directions @ directions.T) ** 2  # (u_j . u_i)^2 = u_j^T (u_i u_i^T) u_j
    coefficients, _ = nnls(design, np.asarray(importance, float))
    return np.einsum("i,ij,ik->jk", coefficients, directions, directions)


def alignment(covariance: np.ndarray, importance: np.ndarray) -> dict[str, float]:
    """The rank correlations (Spearman) between the demonstrations' precision and the measured
    ``importance`` ``(2 m,)`` (of :func:`probe_directions`' order, ``covariance`` ``(m, m)``):
    ``"eigen"`` over the covariance's m eigen-directions (``1 / eigenvalue``), ``"diagonal"``
    over the m task dimensions (``1 / variance``); NaN where either side is constant."""
    values = np.linalg.eigvalsh(covariance)  # ascending: the probe's order
    floor, m = 1e-12, len(covariance)
    pairs = {
        "eigen": (1.0 / np.maximum(values, floor), importance[m:]),
        "diagonal": (1.0 / np.maximum(np.diag(covariance), floor), importance[:m]),
    }
    out = {}
    for name, (precision, measured) in pairs.items():
        constant = np.ptp(precision) == 0 or np.ptp(measured) == 0
        out[name] = float("nan") if constant else float(spearmanr(precision, measured)[0])
    return out



def results_folder(run_dir: Path) -> Path:
    """Where ``run_dir`` keeps its teachers' results."""
    return Path(run_dir) / "sensitivity"


def result_path(run_dir: Path, seed: int) -> Path:
    """Where teacher ``seed``'s result is kept in ``run_dir``."""
    return results_folder(run_dir) / f"seed-{seed}.json"


def model_digest(model_bytes: bytes) -> str:
    """The SHA-256 a result names its teacher's ``model.npz`` by."""
    return hashlib.sha256(model_bytes).hexdigest()


def with_importance(run_dir: Path, models: Sequence[Teacher]) -> list[Teacher]:
    """``models`` with each teacher's measured importance (:attr:`Learned.importance`):
    ``Q + I / k^2`` of its result in ``run_dir``.

    Raises:
        ImitateError: a teacher without a usable result, or with one measured on another
            model.
    """
    measure_it = (f"imitate sensitivity {run_dir} --teachers N [--confirm M] measures the run's "
                  "teachers")
    out = []
    for t in models:
        path = result_path(run_dir, t.seed)
        if not path.exists():
            raise ImitateError(
                f"similarity 'importance' needs teacher {t.seed}'s measured tolerance; {path} "
                f"is missing: {measure_it}"
            )
        result = load_json(path, hint=measure_it)
        if not isinstance(result, dict) or result.get("model") != model_digest(t.model_bytes):
            raise ImitateError(
                f"{path} was measured on another model than teacher {t.seed}'s (learned again "
                f"since, or an older result): {measure_it}"
            )
        try:
            form = np.asarray(result["quadratic_form"], float)
            floor = 1.0 / max(result["magnitudes"]) ** 2
        except (KeyError, TypeError, ValueError):
            form, floor = np.empty(0), np.nan
        # Square: its size the planner checks against the model's.
        if form.ndim != 2 or form.shape[0] != form.shape[1] or not np.isfinite(floor):
            raise ImitateError(f"{path} holds no usable quadratic form: {measure_it}")
        form = form + floor * np.eye(len(form))
        learned = dataclasses.replace(t.learned, importance=form)
        out.append(dataclasses.replace(t, learned=learned))
    return out
