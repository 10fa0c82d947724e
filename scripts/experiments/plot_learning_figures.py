"""Learning figures on synthetic pouring demonstrations: Fig. 4, Fig. 5 and the GMR bands.

Writes ``fig4_gmm_dtw.png``, ``fig5_bic.png`` and ``gmr.png`` to the output directory and prints
the chosen numbers of components and the pouring-phase variance ratio (without / with DTW).

Usage: ``python scripts/experiments/plot_learning_figures.py --out runs/figures``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from imitate.demos.synthetic import SyntheticConfig, phased_demos
from imitate.figures.plots import (
    figure_png,
    plot_bic_curves,
    plot_gmm_with_and_without_dtw,
    plot_gmr,
)
from imitate.learning import LearningConfig, learn
from imitate.learning.bic import bic_sweep
from imitate.learning.gmr import gmr
from imitate.rundir.artifacts import save_bytes
from imitate.taskspace import EQ1


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="output directory")
    parser.add_argument("--seed", type=int, default=0, help="seed of the synthetic demos")
    parser.add_argument("--k-max", type=int, default=30, help="largest K of the BIC sweep")
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)

    sd = phased_demos(SyntheticConfig(seed=args.seed))
    aligned = learn(
        sd.demos, rate=sd.rate, config=LearningConfig(k_max=args.k_max, bic_method="fast")
    )
    k = aligned.gmm.n_components
    raw = learn(sd.demos, rate=sd.rate, config=LearningConfig(n_components=k, use_dtw=False))
    figure = plot_gmm_with_and_without_dtw(raw, aligned, dim=3)
    save_bytes(args.out / "fig4_gmm_dtw.png", figure_png(figure))

    full = bic_sweep(aligned.data, args.k_max, "full")
    curves = {"fast (K-means only)": aligned.bic_curve, "full (EM)": full.curve}
    save_bytes(args.out / "fig5_bic.png", figure_png(plot_bic_curves(curves)))
    save_bytes(args.out / "gmr.png", figure_png(plot_gmr(aligned)))
    print(f"K chosen: fast {k}, full {full.k}")

    start, end = sd.act_windows[aligned.alignment.reference]
    pour = (aligned.times >= start) & (aligned.times <= end)
    for covariance in ("paper", "total"):
        var = [
            np.diagonal(gmr(m.gmm, aligned.times[pour], covariance=covariance)[1], 0, 1, 2)
            for m in (raw, aligned)
        ]
        ratio = var[0].mean(axis=0) / var[1].mean(axis=0)
        text = ", ".join(f"{n} {r:.2f}" for n, r in zip(EQ1.labels(), ratio, strict=True))
        print(f"pouring-phase variance without/with DTW ({covariance}): {text}")
    print(f"figures written to {args.out}")


if __name__ == "__main__":
    main()
