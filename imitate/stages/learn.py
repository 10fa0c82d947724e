"""The ``learn`` stage: task space, DTW, GMM (components by BIC), GMR (``model.npz``)."""

from __future__ import annotations

import dataclasses
import time
from pathlib import Path

import numpy as np

from imitate.demos import space_selection
from imitate.demos.oracle import true_demos
from imitate.demos.segment import task_demos
from imitate.envs.task import Task
from imitate.envs.teacher_motion import script_demonstrations
from imitate.learning import LearningConfig, learn
from imitate.learning.bic import bic_sweep
from imitate.stages.config import RunConfig
from imitate.stages.files import DemosFile, Learned, ModelFile, ObservationsFile


def run(run_dir: Path, config: RunConfig, task: Task) -> dict:
    """The task space (``task``'s, the one its demonstrations select, TP-GMM's candidate frames
    side by side, or the one ``config.task_space`` names), DTW, GMM (components by BIC), GMR;
    the other BIC method for comparison."""
    space, ratios = task.space, []
    if config.task_space == "tpgmm":
        # TP-GMM's frames stand still in a scene: the world's, not an object's own
        space = space_selection.candidates(task.space.places, world=False, own_frames=False)
    elif config.task_space == "auto":
        cut = DemosFile.load(run_dir)
        rated = space_selection.rate(cut.segments, cut.objects, cut.gaze, task,
                                     smoothing=config.smoothing)
        space = space_selection.select(rated, len(cut.segments))
        ratios = [[t.name, value] for t, value in rated.items()]
    elif config.task_space != "declared":  # named by its relations (RunConfig checked them)
        space = space_selection.named(config.task_space, task.space.places)
    if config.oracle:
        tracks = ObservationsFile.load(run_dir).observations.tracks
        motion = script_demonstrations(config.teacher())
        demos = true_demos(motion, tracks.gaze, tracks.times, space)
        gaze, rate = tracks.gaze, config.fps
        bridged = 0
    else:
        cut = DemosFile.load(run_dir)
        gaze = cut.gaze
        bridged = sum(int(np.isnan(d.position).any(axis=-1).sum()) for d in cut.segments)
        demos, rate = task_demos(cut.segments, cut.objects, gaze, space,
                                 smoothing=config.smoothing)
    k_max = min(config.k_max, *(len(d) for d in demos))
    settings = LearningConfig(k_max=k_max, bic_method=config.bic, seed=config.seed)
    start = time.perf_counter()
    model = learn(demos, rate=rate, config=settings)
    seconds = time.perf_counter() - start
    other = "fast" if config.bic == "full" else "full"
    other_sweep = bic_sweep(model.data, k_max, other, config.seed)
    curves = {config.bic: model.bic_curve, other: other_sweep.curve}
    chosen = {config.bic: model.gmm.n_components, other: int(other_sweep.k)}
    raw = learn(
        demos, rate=rate,
        config=dataclasses.replace(settings, n_components=model.gmm.n_components, use_dtw=False),
    )
    assert model.alignment is not None  # learned with DTW (LearningConfig's default)
    ModelFile(
        Learned(model, gaze, space=None if config.task_space == "declared" else space,
                frames=config.task_space == "tpgmm"),
        raw=raw, rate=rate, bic_fast=curves["fast"], bic_full=curves["full"],
        aligned=np.asarray(model.alignment.aligned),
    ).save(run_dir)
    return {
        "learning": {
            "source": "ground truth (oracle)" if config.oracle else "perception",
            "bic": config.bic,
            "n_components": model.gmm.n_components,
            "n_components_fast_bic": chosen["fast"],
            "n_components_full_bic": chosen["full"],
            "seconds": seconds,
            "bridged_samples": bridged,
            "task_space": " ".join(f"({term})" for term in space.text),
            "space_ratios": ratios,
        }
    }
