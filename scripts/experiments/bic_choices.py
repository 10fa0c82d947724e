"""The number of components each BIC sweep chooses on the learned data of run directories.

    python scripts/experiments/bic_choices.py runs/latest runs/seed20 runs/seed21 ...

Runs the fast (paper) and the full sweep on every run's ``model.npz: data`` (the aligned,
time-stacked demonstrations, shape ``(N, 1 + m)``) with the run's ``k_max`` (the length of its
stored BIC curve) and seed, prints one
row per run and how often the fast sweep chooses fewer, as many or more components (the paper's
Fig. 5 has the fast one choose more).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from imitate.errors import ImitateError
from imitate.learning.bic import bic_sweep
from imitate.rundir.artifacts import load_json
from imitate.stages.files import ModelFile


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories")
    args = parser.parse_args()
    print(f"{'run':<28}{'N':>6}{'K fast':>8}{'K full':>8}")
    tally = {"fewer": 0, "as many": 0, "more": 0}
    for run in args.runs:
        try:
            seed = load_json(run / "config.json")["seed"]
            learning = ModelFile.load(run)
        except ImitateError as err:
            sys.exit(f"bic_choices: {err}")
        data, k_max = learning.learned.model.data, len(learning.bic_full)
        fast, full = (bic_sweep(data, k_max, m, seed).k for m in ("fast", "full"))
        tally["fewer" if fast < full else "more" if fast > full else "as many"] += 1
        print(f"{str(run):<28}{len(data):>6}{fast:>8}{full:>8}")
    print("fast sweep chooses " + ", ".join(f"{name} {n}" for name, n in tally.items())
          + f" of {len(args.runs)}")


if __name__ == "__main__":
    main()
