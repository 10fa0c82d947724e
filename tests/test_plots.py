"""Figures drawn in a worker process are the figures drawn here."""

import numpy as np

from imitate.figures import drawing, plots


def test_a_figure_drawn_by_the_drawing_process_is_the_one_drawn_here():
    curves = {"fast (K-means only)": np.linspace(3.0, 1.0, 8), "full (EM)": np.geomspace(3, 2, 8)}
    here = plots.figure_png(plots.plot_bic_curves(curves))
    with drawing.worker() as worker:
        drawn = worker.submit(plots.png, plots.plot_bic_curves, curves).result(timeout=120)
    assert drawn[:8] == b"\x89PNG\r\n\x1a\n"
    assert drawn == here
