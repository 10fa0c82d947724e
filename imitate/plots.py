"""Figures of a run: tracked against true trajectories, Fig. 4 (GMM with and without DTW),
Fig. 5 (BIC), GMR bands, Fig. 9 (reproductions over a sweep of collision weights), costs.

Every ``plot_*`` function draws on a new matplotlib figure and returns it; :func:`save` writes
one atomically and frees it. The backend is matplotlib's choice (Agg where there is no display);
the ``imitate`` command sets Agg.
"""

from __future__ import annotations

from collections.abc import Sequence

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse

from imitate.artifacts import write_atomic
from imitate.gmm import GMM
from imitate.learning import LearnedModel
from imitate.taskspace import TASK_DIMS, TASK_UNITS

__all__ = [
    "plot_bic_curves",
    "plot_collision_sweep",
    "plot_costs",
    "plot_gmm_with_and_without_dtw",
    "plot_gmr",
    "plot_observation",
    "plot_snapshots",
    "save",
]


def _ellipse(ax, mean: np.ndarray, cov: np.ndarray, n_std: float = 2.0, **kwargs) -> None:
    """Draws the ``n_std`` ellipse of a 2-D Gaussian."""
    values, vectors = np.linalg.eigh(cov)
    angle = np.degrees(np.arctan2(vectors[1, -1], vectors[0, -1]))
    width, height = 2 * n_std * np.sqrt(np.maximum(values[::-1], 0.0))
    ax.add_patch(Ellipse(mean, width, height, angle=angle, **kwargs))


def _gmm_panel(ax, data: np.ndarray, gmm: GMM, column: int, title: str) -> None:
    """Demonstrations (time restarts at 0 for each) and the components' 2-sigma ellipses."""
    for demo in np.split(data, np.flatnonzero(data[:, 0] == 0.0)[1:]):
        ax.plot(demo[:, 0], demo[:, column], color="0.55", lw=0.8)
    idx = np.array([0, column])
    for mean, cov in zip(gmm.means_[:, idx], gmm.covariances_[:, idx[:, None], idx], strict=True):
        _ellipse(ax, mean, cov, facecolor="none", edgecolor="tab:green", lw=1.5)
    ax.set_title(f"{title} (K = {gmm.n_components})")
    ax.set_xlabel("t [s]")


def plot_gmm_with_and_without_dtw(raw: LearnedModel, aligned: LearnedModel, dim: int = 3) -> Figure:
    """Fig. 4: GMM components (2-sigma ellipses) over one task dimension and time.

    Args:
        raw: Model learned without DTW (``LearningConfig(use_dtw=False)``).
        aligned: Model learned with DTW.
        dim: Task-space dimension to show (index into :data:`imitate.taskspace.TASK_DIMS`).

    Returns:
        The figure.
    """
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True, layout="constrained")
    _gmm_panel(axes[0], raw.data, raw.gmm, dim + 1, "without DTW")
    _gmm_panel(axes[1], aligned.data, aligned.gmm, dim + 1, "with DTW")
    axes[0].set_ylabel(f"{TASK_DIMS[dim]} [{TASK_UNITS[dim]}]")
    return fig


def plot_bic_curves(curves: dict[str, np.ndarray]) -> Figure:
    """Fig. 5: BIC over the number of components for each heuristic, minima marked.

    Args:
        curves: Heuristic name -> BIC for ``K = 1..k_max``, shape ``(k_max,)``.

    Returns:
        The figure.
    """
    fig, ax = plt.subplots(figsize=(6, 3.8), layout="constrained")
    for name, curve in curves.items():
        k = np.arange(1, len(curve) + 1)
        (line,) = ax.plot(k, curve, marker=".", label=f"{name} (K = {int(np.argmin(curve)) + 1})")
        ax.plot(np.argmin(curve) + 1, curve.min(), "o", color=line.get_color(), ms=9, mfc="none")
    ax.set_xlabel("number of components K")
    ax.set_ylabel("BIC")
    ax.legend()
    return fig


def plot_gmr(model: LearnedModel, demos: Sequence[np.ndarray] | None = None) -> Figure:
    """GMR mean +- 2 sigma over time for every task-space dimension.

    Args:
        model: A learned model.
        demos: Demonstrations to overlay, each of shape ``(n_steps, 7)`` on the model's time
            axis; the aligned ones if ``None`` and the model used DTW.

    Returns:
        The figure.
    """
    if demos is None and model.alignment is not None:
        demos = list(model.alignment.aligned)
    n_dims = model.mean.shape[1]
    fig, axes = plt.subplots(n_dims, 1, figsize=(7, 1.6 * n_dims), sharex=True,
                             layout="constrained")
    sigma = np.sqrt(model.variance)
    for d, ax in enumerate(np.atleast_1d(axes)):
        for demo in demos or ():
            ax.plot(model.times[: len(demo)], demo[:, d], color="0.6", lw=0.7)
        ax.fill_between(model.times, model.mean[:, d] - 2 * sigma[:, d],
                        model.mean[:, d] + 2 * sigma[:, d], color="tab:blue", alpha=0.3)
        ax.plot(model.times, model.mean[:, d], color="tab:blue", lw=1.5)
        name = TASK_DIMS[d] if n_dims == len(TASK_DIMS) else f"x{d}"
        unit = TASK_UNITS[d] if n_dims == len(TASK_DIMS) else ""
        ax.set_ylabel(f"{name}\n[{unit}]" if unit else name, fontsize=8)
    np.atleast_1d(axes)[-1].set_xlabel("t [s]")
    return fig


def plot_observation(observations, boundaries: np.ndarray | None = None) -> Figure:
    """Tracked against true object trajectories, with the demonstration boundaries.

    Args:
        observations: :class:`imitate.perception.Observations`; the true tracks are drawn when
            it carries ground truth, their demonstrations shaded.
        boundaries: ``(n_demos, 2)`` detected demonstration start and end [s], drawn as
            vertical lines (green start, red end).

    Returns:
        The figure: per object, its tracked point x, y, z [m] and its angle around the gaze
        vector [deg].
    """
    tracks, truth = observations.tracks, observations.truth
    rows = [(k, c) for k in range(len(tracks.objects)) for c in range(4)]
    fig, axes = plt.subplots(
        len(rows), 1, figsize=(10, 1.25 * len(rows)), sharex=True, layout="constrained"
    )
    t = tracks.times
    for ax, (k, c) in zip(axes, rows, strict=True):
        if c < 3:
            tracked = tracks.position[k, :, c]
            true = truth.position[k, :, c] if truth is not None else None
            label = f"{tracks.objects[k]} {'xyz'[c]}\n[m]"
        else:
            tracked = np.degrees(tracks.angle[k])
            true = np.degrees(truth.angle[k]) if truth is not None else None
            label = f"{tracks.objects[k]} angle\n[deg]"
        if true is not None:
            ax.plot(t, true, color="0.2", lw=1.6, label="true")
            for start, end in truth.boundaries:
                ax.axvspan(start, end, color="0.85", lw=0)
        ax.plot(t, tracked, color="tab:orange", lw=0.9, label="tracked")
        missing = ~tracks.detected[k]
        if missing.any():
            ax.plot(t[missing], tracked[missing], "x", color="tab:red", ms=3, label="gap")
        for start, end in boundaries if boundaries is not None else ():
            ax.axvline(start, color="tab:green", lw=0.9)
            ax.axvline(end, color="tab:red", lw=0.9)
        ax.set_ylabel(label, fontsize=8)
    axes[0].legend(loc="upper right", fontsize=7, ncol=3)
    axes[-1].set_xlabel("t [s]")
    return fig


def plot_collision_sweep(
    times: np.ndarray,
    mean: np.ndarray,
    variance: np.ndarray,
    reproductions: dict[float, np.ndarray],
    dim: int = 2,
) -> Figure:
    """Fig. 9: one task dimension over time, GMR mean +- sigma and the reproduction for each
    collision weight.

    Args:
        times: ``(T,)`` [s].
        mean, variance: GMR mean and variance at ``times``, ``(T, 7)``.
        reproductions: ``{collision weight: task states (T, 7)}``.
        dim: Task dimension (default ``dz``, the paper's).
    """
    fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    sd = np.sqrt(variance[:, dim])
    ax.fill_between(times, mean[:, dim] - sd, mean[:, dim] + sd, color="0.85",
                    label="GMR mean +- sigma")
    ax.plot(times, mean[:, dim], "k--", lw=1)
    for weight, x in reproductions.items():
        ax.plot(times, x[:, dim], label=f"collision weight {weight:g}")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"{TASK_DIMS[dim]} [{TASK_UNITS[dim]}]")
    ax.legend(fontsize=8)
    return fig


def plot_costs(costs: dict[float, np.ndarray]) -> Figure:
    """Total cost per optimiser iteration, ``{collision weight: (n_iter + 1,)}``."""
    fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    for weight, total in costs.items():
        ax.semilogy(total, label=f"collision weight {weight:g}")
    ax.set_xlabel("iteration")
    ax.set_ylabel("total cost")
    ax.legend(fontsize=8)
    return fig


def plot_snapshots(images: Sequence[np.ndarray], times: Sequence[float]) -> Figure:
    """Paper Fig. 8: a row of rendered snapshots ``(h, w, 3) uint8``, titled with their time
    [s]."""
    fig, axes = plt.subplots(1, len(images), figsize=(2.6 * len(images), 2.3),
                             layout="constrained")
    for ax, image, t in zip(np.atleast_1d(axes), images, times, strict=True):
        ax.imshow(image)
        ax.set_title(f"t = {t:.1f} s", fontsize=9)
        ax.set_axis_off()
    return fig


def save(fig: Figure, path, dpi: int = 110) -> None:
    """Write ``fig`` as a PNG to ``path`` atomically and close it."""
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=dpi))
    plt.close(fig)
