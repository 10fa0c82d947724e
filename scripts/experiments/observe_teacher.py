"""Watch the teacher: render its demonstrations from the robot's eyes, track, segment, plot.

Writes ``observations.npz``, ``demos.npz`` and ``figures/observation.png`` into ``--out``.

    python scripts/experiments/observe_teacher.py --out runs/observe [--seed 0] \
        [--width 640 --height 480]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from imitate.demos.segment import StillnessConfig, segment
from imitate.envs.observation import ObservationConfig
from imitate.envs.teacher_motion import TeacherConfig
from imitate.figures.plots import figure_png, plot_observation
from imitate.perception.watch import watch
from imitate.rundir import layout
from imitate.rundir.artifacts import save_bytes
from imitate.stages.files import DemosFile, ObservationsFile


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True, help="run directory")
    parser.add_argument("--seed", type=int, default=0, help="seed of the teacher's motion")
    parser.add_argument("--demos", type=int, default=5, help="number of demonstrations")
    parser.add_argument("--width", type=int, default=640, help="image width [px]")
    parser.add_argument("--height", type=int, default=480, help="image height [px]")
    parser.add_argument("--fps", type=float, default=30.0, help="camera rate [Hz]")
    args = parser.parse_args(argv)
    config = ObservationConfig(
        teacher=TeacherConfig(n_demos=args.demos, seed=args.seed),
        fps=args.fps,
        width=args.width,
        height=args.height,
    )
    timing = {}
    observations = watch(config, timing=timing, progress=True)
    demos = segment(observations.tracks, StillnessConfig())
    tracks, truth = observations.tracks, observations.truth
    ObservationsFile(observations).save(args.out)
    cut = DemosFile(tuple(demos), tracks.objects, tracks.gaze)
    cut.save(args.out)
    figure = plot_observation(observations, cut.boundaries)
    save_bytes(args.out / layout.figure("observation"), figure_png(figure))
    print(
        f"{timing['pairs']} stereo pairs {args.width}x{args.height}: rendering "
        f"{timing['pairs'] / timing['render']:.1f} pairs/s, tracking + triangulation "
        f"{timing['pairs'] / timing['track']:.0f} pairs/s"
    )
    for k, name in enumerate(tracks.objects):
        err = np.linalg.norm(tracks.position[k] - truth.position[k], axis=-1) * 1e3
        print(
            f"{name}: detected in {tracks.detected[k].mean():.1%} of the pairs, position error "
            f"median {np.nanmedian(err):.1f} mm, 95th percentile {np.nanpercentile(err, 95):.1f} mm"
        )
    print(f"{len(demos)} demonstrations found ({len(truth.boundaries)} shown):")
    for d in demos:
        print(f"  {d.start:6.2f} s .. {d.end:6.2f} s")
    print(f"wrote {args.out}/observations.npz, demos.npz, figures/observation.png")


if __name__ == "__main__":
    main()
