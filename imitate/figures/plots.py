"""Figures of a run: tracked against true trajectories, Fig. 4 (GMM with and without DTW),
Fig. 5 (BIC), GMR bands, Fig. 8 (snapshots without and with the collision cost), Fig. 9
(reproductions over a sweep of collision weights), costs.

Every ``plot_*`` function draws on a new matplotlib figure and returns it; :func:`figure_png`
turns one into PNG bytes and frees it, :func:`png` draws one and does so (in a worker process
too: the functions and their arguments pickle); writing the bytes is the caller's. The backend
is matplotlib's choice (Agg where there is no display); the ``imitate`` command and
:func:`use_agg` set Agg.
"""

from __future__ import annotations

import io
from collections.abc import Callable, Sequence

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.artist import Artist
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse

from imitate.learning import LearnedModel
from imitate.learning.gmm import GMM
from imitate.taskspace import EQ1

DPI = 110  # dots per inch of the saved figures; Fig. 8 shows its snapshots at their pixel size
LOOSE = 0.1  # Fig. 9 marks the steps whose similarity weight is below this share of its largest

__all__ = [
    "DPI",
    "figure_png",
    "plot_bic_curves",
    "plot_collision_sweep",
    "plot_costs",
    "plot_gmm_with_and_without_dtw",
    "plot_gmr",
    "plot_observation",
    "plot_snapshots",
    "png",
    "use_agg",
]


def _ellipse(ax, mean: np.ndarray, cov: np.ndarray, n_std: float = 2.0, **kwargs) -> None:
    """Draws the ``n_std`` ellipse of a 2-D Gaussian."""
    values, vectors = np.linalg.eigh(cov)
    angle = np.degrees(np.arctan2(vectors[1, -1], vectors[0, -1]))
    width, height = 2 * n_std * np.sqrt(np.maximum(values[::-1], 0.0))
    # matplotlib's stubs want a tuple for xy; any (2,) array-like is accepted.
    ax.add_patch(Ellipse(mean, width, height, angle=angle, **kwargs))  # type: ignore[arg-type]


def _gmm_panel(ax, data: np.ndarray, gmm: GMM, column: int, title: str) -> None:
    """Demonstrations (time restarts at 0 for each) and the components' 2-sigma ellipses."""
    for demo in np.split(data, np.flatnonzero(data[:, 0] == 0.0)[1:]):
        ax.plot(demo[:, 0], demo[:, column], color="0.55", lw=0.8)
    idx = np.array([0, column])
    for mean, cov in zip(gmm.means_[:, idx], gmm.covariances_[:, idx[:, None], idx], strict=True):
        _ellipse(ax, mean, cov, facecolor="none", edgecolor="tab:green", lw=1.5)
    ax.set_title(f"{title} (K = {gmm.n_components})")
    ax.set_xlabel("t [s]")


def plot_gmm_with_and_without_dtw(
    raw: LearnedModel, aligned: LearnedModel, dim: int = 3,
    labels: Sequence[str] = EQ1.labels(), units: Sequence[str] = EQ1.units,
) -> Figure:
    """Fig. 4: GMM components (2-sigma ellipses) over one task dimension and time.

    Args:
        raw: Model learned without DTW (``LearningConfig(use_dtw=False)``).
        aligned: Model learned with DTW.
        dim: Task-space dimension to show (index into ``labels``).
        labels: The task-space dimensions' labels (the task's ``dims``).
        units: Their units (its space's).

    Returns:
        The figure.
    """
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8), sharey=True, layout="constrained")
    _gmm_panel(axes[0], raw.data, raw.gmm, dim + 1, "without DTW")
    _gmm_panel(axes[1], aligned.data, aligned.gmm, dim + 1, "with DTW")
    axes[0].set_ylabel(f"{labels[dim]} [{units[dim]}]")
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


def plot_gmr(
    model: LearnedModel, demos: Sequence[np.ndarray] | None = None,
    labels: Sequence[str] = EQ1.labels(), units: Sequence[str] = EQ1.units,
) -> Figure:
    """GMR mean +- 2 sigma over time for every task-space dimension.

    Args:
        model: A learned model.
        demos: Demonstrations to overlay, each of shape ``(n_steps, m)`` on the model's time
            axis; the aligned ones if ``None`` and the model used DTW.
        labels: The task-space dimensions' labels (the task's ``dims``); ``x0, x1, ...``
            without a unit where the model has another number of dimensions.
        units: Their units (its space's).

    Returns:
        The figure.
    """
    if demos is None and model.alignment is not None:
        demos = list(model.alignment.aligned)
    n_dims: int = model.mean.shape[1]
    fig, axes = plt.subplots(n_dims, 1, figsize=(7, 1.6 * n_dims), sharex=True,
                             layout="constrained")
    sigma = np.sqrt(model.variance)
    for d, ax in enumerate(np.atleast_1d(axes)):
        for demo in demos or ():
            ax.plot(model.times[: len(demo)], demo[:, d], color="0.6", lw=0.7)
        ax.fill_between(model.times, model.mean[:, d] - 2 * sigma[:, d],
                        model.mean[:, d] + 2 * sigma[:, d], color="tab:blue", alpha=0.3)
        ax.plot(model.times, model.mean[:, d], color="tab:blue", lw=1.5)
        name = labels[d] if n_dims == len(labels) else f"x{d}"
        unit = units[d] if n_dims == len(units) else ""
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
    clearance: dict[float, np.ndarray],
    similarity: np.ndarray | None = None,
    n_dims: int = 2,
    labels: Sequence[str] = EQ1.labels(),
    units: Sequence[str] = EQ1.units,
    position: slice = EQ1.positions[0],
) -> Figure:
    """Fig. 9: the reproductions over a sweep of collision weights.

    Panels: the ``n_dims`` dimensions of the main relative position in which the reproductions
    differ most (against the GMR mean +- 2 sigma, with the steps where that dimension's similarity
    weight is below :data:`LOOSE` of its largest: eq. 21 near the dimension's largest variance,
    where it reaches 0); each reproduction's distance from the smallest weight's (against the steps
    of high GMR variance); each one's clearance. Steps in collision (clearance < 0) are marked on
    every curve.

    Args:
        times: ``(T,)`` [s].
        mean: ``(T, m)`` GMR mean of the task state at ``times`` (in ``units``).
        variance: ``(T, m)`` GMR variance of each task dimension at ``times`` (those units
            squared).
        reproductions: ``{collision weight: task states (T, m)}``.
        clearance: ``{collision weight: smallest signed distance (T,) [m]}``.
        similarity: ``(T, m)`` diagonals of the similarity weights ``W_t``, or ``None``.
        n_dims: How many of the main position's ``dx, dy, dz`` to show.
        labels: The task-space dimensions' labels (the task's ``dims``).
        units: Their units (its space's).
        position: The main relative position's columns (its space's first).
    """
    weights = sorted(reproductions)
    first = reproductions[weights[0]][:, position]
    change = {w: 1e3 * np.linalg.norm(reproductions[w][:, position] - first, axis=1)
              for w in weights}
    spread = np.max([np.abs(x[:, position] - first).max(axis=0) for x in reproductions.values()],
                    axis=0)
    dims = position.start + np.sort(np.argsort(spread)[::-1][:n_dims])
    colours = dict(zip(weights, plt.cm.viridis(np.linspace(0.0, 0.85, len(weights))), strict=True))
    fig, axes = plt.subplots(
        n_dims + 2, 1, figsize=(9, 2.4 * (n_dims + 2)), sharex=True, layout="constrained"
    )
    for ax, d in zip(axes, dims, strict=False):
        sd = np.sqrt(variance[:, d])
        ax.fill_between(times, mean[:, d] - 2 * sd, mean[:, d] + 2 * sd, color="0.86",
                        label="GMR mean ± 2σ")
        ax.plot(times, mean[:, d], "k--", lw=1.2, label="GMR mean")
        if similarity is not None:
            loose = similarity[:, d] < LOOSE * similarity[:, d].max()
            ax.fill_between(times, 0.0, 1.0, where=loose, color="tab:orange", alpha=0.25, lw=0,
                            transform=ax.get_xaxis_transform(),
                            label=f"similarity weight below {LOOSE:.0%} of its largest")
        _sweep_curves(ax, times, {w: reproductions[w][:, d] for w in weights}, clearance, colours)
        ax.set_ylabel(f"{labels[d]} [{units[d]}]")
    ax = axes[-2]
    position_variance = variance[:, position].sum(axis=1)
    ax.fill_between(times, 0.0, 1.0, where=position_variance > np.median(position_variance),
                    color="#d5e5f5", lw=0, transform=ax.get_xaxis_transform(),
                    label="GMR position variance above its median")
    _sweep_curves(ax, times, change, clearance, colours)
    ax.set_ylim(0.0, 1.3 * max(*(c.max() for c in change.values()), 1e-3))
    ax.set_ylabel(f"distance from\nweight {weights[0]:g} [mm]")
    ax = axes[-1]
    ax.axhspan(1.1e3 * min(0.0, *(c.min() for c in clearance.values())), 0.0,
               color="tab:red", alpha=0.1, lw=0, label="penetration (clearance < 0)")
    _sweep_curves(ax, times, {w: 1e3 * clearance[w] for w in weights}, clearance, colours)
    ax.set_ylabel("planned\nclearance [mm]")
    ax.set_xlabel("t [s]")
    handles: dict[str, Artist] = {}
    for a in axes:
        handles.update(zip(*a.get_legend_handles_labels()[::-1], strict=True))
    order = sorted(handles, key=lambda label: ("collision" in label, "penetration" in label))
    fig.legend([handles[k] for k in order], order, loc="outside right center", fontsize=8)
    return fig


def _sweep_curves(ax, times, curves: dict, clearance: dict, colours: dict) -> None:
    """One line per collision weight, its steps in collision marked with red dots."""
    for weight, y in curves.items():
        ax.plot(times, y, color=colours[weight], lw=1.6, label=f"collision weight {weight:g}")
        hit = clearance[weight] < 0.0
        ax.plot(times[hit], y[hit], "o", color="tab:red", ms=3.5, mec="none",
                label="in collision (clearance < 0)")


def plot_costs(costs: dict[float, np.ndarray]) -> Figure:
    """Total cost per optimizer iteration, ``{collision weight: (n_iter + 1,)}``."""
    fig, ax = plt.subplots(figsize=(7, 4), layout="constrained")
    for weight, total in costs.items():
        ax.semilogy(total, label=f"collision weight {weight:g}")
    ax.set_xlabel("iteration")
    ax.set_ylabel("total cost")
    ax.legend(fontsize=8)
    return fig


def plot_snapshots(
    rows: Sequence[tuple[str, Sequence[np.ndarray], Sequence[str | None]]],
    times: Sequence[float],
) -> Figure:
    """Paper Fig. 8: rows of rendered snapshots ``(h, w, 3) uint8`` at the same ``times`` [s],
    shown at their pixel size.

    Args:
        rows: ``(title, images, marks)`` per row; a panel whose mark is not ``None`` is framed
            in red with the mark written under it (a collision, say).
        times: The snapshots' times, titling the columns.
    """
    h, w = rows[0][1][0].shape[:2]
    fig = plt.figure(figsize=(len(times) * w / DPI, len(rows) * (h + 70) / DPI), dpi=DPI)
    subfigs = fig.subfigures(len(rows), 1, squeeze=False)[:, 0]  # one row: still an array
    for subfig, (title, images, marks) in zip(subfigs, rows, strict=True):
        subfig.suptitle(title, fontsize=12, fontweight="bold")
        axes = subfig.subplots(1, len(images), gridspec_kw={
            "left": 0.003, "right": 0.997, "bottom": 0.005, "top": 1 - 62 / (h + 70),
            "wspace": 0.02,
        })
        for ax, image, mark, t in zip(np.atleast_1d(axes), images, marks, times, strict=True):
            ax.imshow(image, interpolation="none")
            ax.set_title(f"t = {t:.1f} s", fontsize=10)
            ax.set_xticks([])
            ax.set_yticks([])
            if mark is not None:
                ax.spines[:].set(color="tab:red", linewidth=4)
                ax.text(0.5, 0.03, mark, transform=ax.transAxes, ha="center", va="bottom",
                        color="white", fontsize=9, fontweight="bold",
                        bbox={"facecolor": "tab:red", "edgecolor": "none", "pad": 2})
            else:
                ax.spines[:].set_visible(False)
    return fig


def figure_png(fig: Figure, dpi: int = DPI) -> bytes:
    """``fig`` as PNG bytes at ``dpi``; the figure is closed."""
    buffer = io.BytesIO()
    try:
        fig.savefig(buffer, format="png", dpi=dpi)
    finally:
        plt.close(fig)
    return buffer.getvalue()


def png(draw: Callable[..., Figure], *args, dpi: int = DPI) -> bytes:
    """The figure ``draw(*args)`` returns, as PNG bytes (:func:`figure_png`)."""
    return figure_png(draw(*args), dpi)


def use_agg() -> None:
    """Draw with Agg, matplotlib's raster backend, display or not (as the drawing worker process
    does, :mod:`imitate.figures.drawing`)."""
    matplotlib.use("Agg")
