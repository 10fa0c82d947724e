"""Do the robot's pixel observations carry the task? Its workspace camera over replays of a run's
plan, as ``imitate export --images`` records them.

Usage: ``python scripts/experiments/camera_probe.py RUN_DIR [--out DIR] [--episodes 8]``
(e.g. ``runs/latest``).

1. Replays the run's plan as the export does (:func:`imitate.export.episodes.recorded`, the
   env's pixel observations at 160x120) and counts the frames in which the bottle's green and
   the glass's blue show (the tracker's colour ranges, :func:`imitate.perception.colour
   .object_models`), and, for comparison, the frames of the stereo eyes that do.
2. Saves the workspace camera's frames at the start, the pour (the first with half the liquid in
   the glass) and the end as ``OUT/camera_{start,pour,end}.png`` (320x240).
3. A linear probe: replays the plan ``--episodes`` times from other seeds and grasps (the env's
   reset options, drawn within ``GRASP_RANGE``), and regresses the bottle's tilt [deg] and the
   pour fraction on image features alone (the two objects' colour-blob moments in the 80x60
   image: area, centroid, second moments), with ridge least squares in numpy. Leave-two-
   episodes-out: each fold's error on its held-out episodes against the training mean's.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

from imitate.envs.assembly import GRASP_RANGE
from imitate.envs.task import get_task
from imitate.export.episodes import recorded
from imitate.models import humanoid, objects
from imitate.perception.colour import object_models
from imitate.run import load_run

SIZE = (160, 120)  # the replays' images (width, height) [px]
PROBE_SIZE = (80, 60)  # what the probe sees [px]
RIDGE = 1e-3  # of the standardized features' least squares


def masks(image: np.ndarray) -> list[np.ndarray]:
    """The bottle's and the glass's colour masks (bool ``(h, w)``) of an RGB image."""
    hsv = cv2.cvtColor(image, cv2.COLOR_RGB2HSV)
    return [m.colour.mask(hsv) > 0 for m in object_models(("bottle", "glass"))]


def features(image: np.ndarray) -> np.ndarray:
    """``(12,)``: per object its area [share of the image], centroid and second central moments
    [image widths], from the image downsampled to :data:`PROBE_SIZE`."""
    small = cv2.resize(image, PROBE_SIZE, interpolation=cv2.INTER_AREA)
    out = []
    for mask in masks(small):
        m = cv2.moments(mask.astype(np.uint8), binaryImage=True)
        area = max(m["m00"], 1.0)
        w = PROBE_SIZE[0]
        out += [m["m00"] / mask.size, m["m10"] / area / w, m["m01"] / area / w,
                m["mu20"] / area / w**2, m["mu02"] / area / w**2, m["mu11"] / area / w**2]
    return np.array(out)


def tilt(episode) -> np.ndarray:
    """The bottle's axis from the vertical at each observation ``(n + 1,)`` [deg]."""
    w, x, y, z = episode.observations[objects.BOTTLE][:, 3:].T
    up = 1.0 - 2.0 * (x**2 + y**2)  # the body z axis's world z component
    return np.degrees(np.arccos(np.clip(up, -1.0, 1.0)))


def replayed(run, seed: int, options: dict, cameras=(humanoid.WORKSPACE,)):
    """The run's plan replayed from ``seed`` with reset ``options``, recorded with pixels."""
    config = run.config
    task = get_task(config.task)
    kwargs = {
        **task.env_kwargs(config.scene()),
        "obs_type": "state_pixels", "width": SIZE[0], "height": SIZE[1], "cameras": cameras,
    }
    return recorded(task, run.plan, task.env(**kwargs), kwargs, seed, options, run.gaze)


def visibility(run, out: Path) -> None:
    config = run.config
    options = get_task(config.task).reset_options(config.options)
    episode = replayed(run, config.seed, options, humanoid.CAMERAS)
    print(f"replay of {run.path}'s plan: {len(episode) + 1} frames at {SIZE[0]}x{SIZE[1]}, "
          f"pour {episode.infos['pour_fraction'][-1]:.2f}")
    print(f"{'camera':10} {'bottle':>14} {'glass':>14} {'both':>14}  median px (bottle, glass)")
    for camera in humanoid.CAMERAS:
        counts = np.array([[m.sum() for m in masks(f)] for f in episode.observations[camera]])
        seen = counts > 0
        n = len(counts)
        print(f"{camera:10} " + " ".join(
            f"{k:>5}/{n} {100 * k / n:5.1f}%" for k in (*seen.sum(0), seen.all(1).sum())
        ) + f"  {np.median(counts, 0).astype(int).tolist()}")
    frames = episode.observations[humanoid.WORKSPACE]
    pour = int(np.argmax(episode.infos["pour_fraction"] >= 0.5))
    for name, k in (("start", 0), ("pour", pour), ("end", len(frames) - 1)):
        path = out / f"camera_{name}.png"
        big = cv2.resize(frames[k], (320, 240), interpolation=cv2.INTER_NEAREST)
        cv2.imwrite(str(path), cv2.cvtColor(big, cv2.COLOR_RGB2BGR))
        print(f"{path}: step {k} ({k * episode.dt:.2f} s), bottle tilt "
              f"{tilt(episode)[k]:.0f} deg, pour {episode.infos['pour_fraction'][k]:.2f}")


def ridge(x: np.ndarray, y: np.ndarray):
    """Ridge least squares on standardized ``x`` ``(n, k)``; returns the predictor."""
    mean, std = x.mean(0), x.std(0) + 1e-12
    z = (x - mean) / std
    a = np.hstack([z, np.ones((len(z), 1))])
    coef = np.linalg.solve(a.T @ a + RIDGE * len(z) * np.eye(a.shape[1]), a.T @ (y - y.mean()))
    return lambda x_new: np.hstack([(x_new - mean) / std, np.ones((len(x_new), 1))]) @ coef \
        + y.mean()


def probe(run, n_episodes: int) -> None:
    rng = np.random.default_rng(0)
    data = []
    for i in range(n_episodes):
        options = {
            "bottle_grasp": float(rng.uniform(*GRASP_RANGE[objects.BOTTLE])),
            "glass_grasp": float(rng.uniform(*GRASP_RANGE[objects.GLASS])),
        }
        episode = replayed(run, run.config.seed + 100 + i, options)
        x = np.array([features(f) for f in episode.observations[humanoid.WORKSPACE]])
        data.append((x, tilt(episode), episode.infos["pour_fraction"]))
        print(f"episode {i}: seed {run.config.seed + 100 + i}, grasps "
              f"{options['bottle_grasp']:.3f} / {options['glass_grasp']:.3f} m, "
              f"{len(x)} frames, pour {data[-1][2][-1]:.2f}")
    folds = [list(range(k, min(k + 2, n_episodes))) for k in range(0, n_episodes, 2)]
    targets = (("bottle tilt", "deg", " deg"), ("pour fraction", "of the bottle's liquid", ""))
    for t, (target, unit, unit_suffix) in enumerate(targets):
        rows = []
        for held in folds:
            train = [d for j, d in enumerate(data) if j not in held]
            test = [d for j, d in enumerate(data) if j in held]
            x, y = np.vstack([d[0] for d in train]), np.concatenate([d[1 + t] for d in train])
            xt, yt = np.vstack([d[0] for d in test]), np.concatenate([d[1 + t] for d in test])
            predicted = ridge(x, y)(xt)
            rmse = np.sqrt(np.mean((predicted - yt) ** 2))
            base = np.sqrt(np.mean((y.mean() - yt) ** 2))
            r2 = 1.0 - np.sum((predicted - yt) ** 2) / np.sum((yt - y.mean()) ** 2)
            rows.append((rmse, base, r2))
        rmse, base, r2 = np.array(rows).T
        print(f"{target} [{unit}], held-out RMSE per fold (probe / mean predictor): " + ", ".join(
            f"{a:.3g}/{b:.3g}" for a, b in zip(rmse, base, strict=True)
        ))
        print(f"  over {len(folds)} folds of 2 held-out episodes: probe RMSE {rmse.mean():.3g} "
              f"against the mean's {base.mean():.3g}{unit_suffix}, R^2 {r2.mean():.3f} "
              f"(min {r2.min():.3f}); the probe wins in {np.sum(rmse < base)} of {len(folds)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--out", type=Path, default=Path("camera_probe"))
    parser.add_argument("--episodes", type=int, default=8)
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    run = load_run(args.run_dir)
    if run.config.task != "pour":
        sys.exit(f"camera_probe.py: {args.run_dir} is a run of task {run.config.task!r}; the "
                 "probe looks for the bottle and the pour")
    visibility(run, args.out)
    probe(run, args.episodes)


if __name__ == "__main__":
    main()
