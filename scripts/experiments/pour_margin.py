"""Why a pour falls short: where the stream met the glass, against the pour, over the replays of
an evaluation (the last one into EVAL_DIR, the folder ``imitate eval`` printed).

Usage: ``python scripts/experiments/pour_margin.py EVAL_DIR`` (e.g.
``runs/latest/eval/default-w10000-variance``). Nothing is re-run: every replay's record holds its
pour fraction, its spilled particles and where the stream met the glass
(:mod:`imitate.envs.pour.geometry`).

Prints, per teacher, its default run (the three pours and the geometry of the first) and over
its replays the share that pour below 0.9; then, over all replays, the pour against the share of
particles that fell through the rim's plane inside the rim (the stream's aim: a pour that misses
there is the stream's geometry, one that does not is what happens in the glass), and the
Spearman correlation of the pour with each geometry number.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
from scipy import stats

from imitate.envs import tasks
from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.evaluation.suite_run import last_records

GEOMETRY = (
    "stream_inside_share", "stream_offset_median_m", "stream_centre_offset_m",
    "mouth_offset_median_m", "mouth_above_rim_min_m", "tilt_max_deg", "pour_seconds",
)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("eval_dir", type=Path)
    args = parser.parse_args()
    try:
        records = last_records(args.eval_dir)
    except ImitateError as err:
        sys.exit(f"pour_margin: {err}")
    summary = json.loads((args.eval_dir / "summary.json").read_text())
    task = summary.get("task", tasks.DEFAULT)
    if task != "pour":
        sys.exit(f"pour_margin: {args.eval_dir} is an evaluation of task {task!r}, not of pouring")
    success_fraction = get_task("pour").score.threshold
    replays = [(r, p) for r in records for p in r["replays"] if p.get("geometry")]
    print(f"{len(records)} variations, {len(replays)} replays with their geometry\n")
    print("teacher  default run: pours        inside  stream [mm]  mouth off/above [mm]  "
          "| replays below 0.9")
    for t in summary["teachers"]:
        run = t["default_run"] or {}
        g = run.get("pour_geometry") or {}
        own = [p for r, p in replays if r["teacher"] == t["seed"]]
        low = sum(p["pour_fraction"] < success_fraction for p in own)
        pours = " ".join(f"{v:.3f}" for v in run.get("pour_fractions", []))
        print(f"{t['seed']:>7}  {pours:<22} {_f(g.get('stream_inside_share'), 1, 6)}  "
              f"{_f(g.get('stream_offset_median_m'), 1000, 11)}  "
              f"{_f(g.get('mouth_offset_median_m'), 1000, 8)} / "
              f"{_f(g.get('mouth_above_rim_min_m'), 1000, 8)}    | {low}/{len(own)}")
    pour = np.array([p["pour_fraction"] for _, p in replays])
    inside = np.array([p["geometry"]["stream_inside_share"] or 0.0 for _, p in replays])
    print("\nreplays by the share of the stream inside the rim:")
    print("inside share   replays  pour mean  pour below 0.9")
    for low, high in ((0.0, 0.8), (0.8, 0.9), (0.9, 0.95), (0.95, 0.999), (0.999, 1.01)):
        chosen = (inside >= low) & (inside < high)
        if chosen.any():
            print(f"{low:5.3f}-{min(high, 1.0):5.3f}  {chosen.sum():8d}  {pour[chosen].mean():9.3f}"
                  f"  {np.sum(pour[chosen] < success_fraction):14d}")
    print("\nSpearman correlation of the pour with (over the replays):")
    for name in GEOMETRY:
        values = np.array([p["geometry"][name] for _, p in replays], dtype=float)
        ok = np.isfinite(values)
        rho, p_value = stats.spearmanr(values[ok], pour[ok])
        print(f"  {name:<24} rho {rho:+.3f}  p {p_value:.1e}  median {np.median(values[ok]):.4f}")


def _f(value, scale: float, width: int) -> str:
    return f"{'-':>{width}}" if value is None else f"{value * scale:{width}.3f}"


if __name__ == "__main__":
    main()
