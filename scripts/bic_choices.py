"""The number of components each BIC sweep chooses on the learned data of run directories.

    python scripts/bic_choices.py runs/latest runs/seed20 runs/seed21 ...

Runs the fast (paper) and the full sweep on every run's ``model.npz: data`` (the aligned,
time-stacked demonstrations, shape ``(N, 1 + m)``) with the run's ``k_max`` and seed, prints one
row per run and how often the fast sweep chooses fewer, as many or more components (the paper's
Fig. 5 has the fast one choose more).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from imitate.bic import bic_sweep


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories")
    args = parser.parse_args()
    print(f"{'run':<28}{'N':>6}{'K fast':>8}{'K full':>8}")
    tally = {"fewer": 0, "as many": 0, "more": 0}
    for run in args.runs:
        config = json.loads((run / "config.json").read_text())
        data = np.load(run / "model.npz")["data"]
        k_max = min(config["k_max"], len(data))
        fast, full = (bic_sweep(data, k_max, m, config["seed"]).k for m in ("fast", "full"))
        tally["fewer" if fast < full else "more" if fast > full else "as many"] += 1
        print(f"{str(run):<28}{len(data):>6}{fast:>8}{full:>8}")
    print("fast sweep chooses " + ", ".join(f"{name} {n}" for name, n in tally.items())
          + f" of {len(args.runs)}")


if __name__ == "__main__":
    main()
