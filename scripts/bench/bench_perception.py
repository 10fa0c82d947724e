"""Benchmark the perception: accuracy against ground truth and speed, printed as a table.

For each seed the teacher's session is rendered from the robot's head cameras (timed on its
own), then tracking + triangulation runs over the stored frames (timed on its own, after one
untimed pair that compiles or loads the tracker's compiled loops), then the tracks are segmented.
Accuracy: 3D error of the tracked point (axis centre at half height), error of the axis angle
around the gaze vector, demonstrations found and the largest boundary error against the
scripted ones.

    python scripts/bench/bench_perception.py [--seeds 0 1 2] [--width 640 --height 480] [--json F]
        [--out DIR] [--task pour]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
from pathlib import Path

import cv2
import mujoco
import numpy as np

from imitate.demos.segment import StillnessConfig, segment
from imitate.envs import tasks
from imitate.envs.observation import ObservationConfig, frames, session
from imitate.envs.rendering import backend
from imitate.envs.teacher_motion import TeacherConfig
from imitate.perception import (
    Observations,
    StereoTracker,
    perception_config,
    track,
)
from imitate.perception.watch import cameras, ground_truth
from imitate.rundir.artifacts import save_npz


def run_seed(
    seed: int, width: int, height: int, out: Path | None = None, task: str = tasks.DEFAULT
) -> dict:
    """Render, track and segment one session of ``task``; returns its measurements.

    With ``out``, the observations are kept as ``out/observations_seed{seed}.npz``.
    """
    config = ObservationConfig(
        teacher=TeacherConfig(seed=seed, task=task), width=width, height=height
    )
    sess = session(config)
    perception = perception_config(sess.motion.objects)
    left, right = cameras(sess)
    timing: dict = {}
    pairs = list(frames(sess, timing))
    # One untimed pair first: the compiled loops are compiled or loaded once per process.
    StereoTracker(left, right, perception).update(*pairs[0])
    tracks = track(StereoTracker(left, right, perception), pairs, sess.times, timing)
    truth = ground_truth(sess, tracks.objects)
    if out is not None:
        projections = np.array([cam.projection for cam in (left, right)])
        observations = Observations(tracks, projections, (width, height), truth)
        save_npz(out / f"observations_seed{seed}.npz", observations.to_arrays())
    row = {
        "seed": seed,
        "pairs": len(pairs),
        "render_pairs_per_s": len(pairs) / timing["render"],
        "track_pairs_per_s": len(pairs) / timing["track"],
        "long_gaps": len(tracks.long_gaps),
        "objects": list(tracks.objects),
    }
    for k, name in enumerate(tracks.objects):
        err = np.linalg.norm(tracks.position[k] - truth.position[k], axis=-1) * 1e3
        turn = np.degrees(np.abs(np.angle(np.exp(1j * (tracks.angle[k] - truth.angle[k])))))
        row[name] = {
            "detected": float(tracks.detected[k].mean()),
            "pos_median_mm": float(np.nanmedian(err)),
            "pos_p95_mm": float(np.nanpercentile(err, 95)),
            "pos_max_mm": float(np.nanmax(err)),
            "angle_median_deg": float(np.nanmedian(turn)),
            "angle_p95_deg": float(np.nanpercentile(turn, 95)),
        }
    demos = segment(tracks, StillnessConfig())
    found = np.array([(d.start, d.end) for d in demos])
    row["demos_found"] = len(demos)
    row["demos_true"] = len(truth.boundaries)
    if len(found) == len(truth.boundaries):
        row["boundary_max_s"] = float(np.abs(found - truth.boundaries).max())
    else:
        row["boundary_max_s"] = float("nan")
    return row


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    parser.add_argument("--json", type=Path, help="also write the rows to this JSON file")
    parser.add_argument("--out", type=Path, help="also keep each seed's observations here")
    parser.add_argument("--task", choices=tasks.NAMES, default=tasks.DEFAULT,
                        help="the task the teacher demonstrates")
    args = parser.parse_args(argv)
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
        f"MUJOCO_GL={backend()}; mujoco {mujoco.__version__}; opencv "
        f"{cv2.__version__}; {args.width}x{args.height}, 30 Hz"
    )
    rows = [run_seed(seed, args.width, args.height, args.out, args.task) for seed in args.seeds]
    head = (
        f"{'seed':>4} {'object':<7} {'det':>6} {'pos med':>8} {'pos p95':>8} {'pos max':>8} "
        f"{'ang med':>8} {'ang p95':>8} {'demos':>6} {'bound':>7} {'track/s':>8} {'render/s':>9}"
    )
    print(head)
    print(
        f"{'':>4} {'':<7} {'':>6} {'[mm]':>8} {'[mm]':>8} {'[mm]':>8} {'[deg]':>8} {'[deg]':>8} "
        f"{'':>6} {'[s]':>7} {'[pairs]':>8} {'[pairs]':>9}"
    )
    for row in rows:
        for name in row["objects"]:
            o = row[name]
            print(
                f"{row['seed']:>4} {name:<7} {o['detected']:>6.1%} {o['pos_median_mm']:>8.2f} "
                f"{o['pos_p95_mm']:>8.2f} {o['pos_max_mm']:>8.2f} {o['angle_median_deg']:>8.2f} "
                f"{o['angle_p95_deg']:>8.2f} {row['demos_found']:>3}/{row['demos_true']:<2} "
                f"{row['boundary_max_s']:>7.3f} {row['track_pairs_per_s']:>8.0f} "
                f"{row['render_pairs_per_s']:>9.1f}"
            )
    print(
        "targets: pos median <= 5 mm, p95 <= 15 mm; angle median <= 2 deg; every demonstration "
        "found, boundaries within 0.15 s; tracking + triangulation >= 200 pairs/s"
    )
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(rows, indent=2) + "\n")


if __name__ == "__main__":
    main()
