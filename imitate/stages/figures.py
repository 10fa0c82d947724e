"""The ``figures`` stage: ``figures/*.png`` and ``video.mp4`` from the run's artifacts."""

from __future__ import annotations

import itertools
import re
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from imitate.envs.assembly import build_model
from imitate.envs.task import Task
from imitate.envs.teacher_motion import script_demonstrations
from imitate.envs.video import captioned, penetrations, replay_frames, teacher_frames, write_video
from imitate.errors import ImitateError
from imitate.figures import drawing, plots
from imitate.models import objects
from imitate.perception import Observations, Tracks
from imitate.rundir import layout
from imitate.rundir.artifacts import save_bytes, write_atomic
from imitate.stages.config import RunConfig
from imitate.stages.files import DemosFile, ModelFile, ObservationsFile, PlanFile, ReplayFile
from imitate.stages.files.replay import FREE, STATES
from imitate.stages.progress import bar

SNAPSHOT_SIZE = (480, 360)  # Fig. 8's panels [px]
TOUCHING_M = 1e-3  # closer than this, parts touch in physics (whose contacts keep them apart)
TEACHER_CAPTION = "teacher demonstrates ({speedup:g}x); inset: robot's eye, tracking"
ROBOT_CAPTION = "robot reproduces (collision weight {weight:g})"
FREE_CAPTION = "robot reproduces without the collision cost (weight 0)"
FREE_AFTER = 1.0  # [s] of the weight-0 replay shown after its plan comes closest
# The teacher's still pauses between demonstrations play this many times faster (at least
# teacher_speedup): a quarter of the session, they would be a quarter of the video's frames.
PAUSE_SPEEDUP = 8.0
# The video's frames render in two threads at once, each with its own renderer: one kept about
# 1.6 of the 2-core CPU's cores busy (Mesa). More do not pay on a GPU: on an H100 machine (16
# cores) the frames took 2.3 s in one thread, 2.1 s in two and 10.8 s in four.
VIDEO_THREADS = 2


def run(run_dir: Path, config: RunConfig, task: Task) -> dict:
    """The figures (``figures/*.png``) and the video: the teacher, then the robot doing the task.

    A worker process (:mod:`imitate.figures.drawing`) draws the figures while this one renders and
    encodes the video."""
    observations = ObservationsFile.load(run_dir).observations
    boundaries = DemosFile.load(run_dir).boundaries
    learning = ModelFile.load(run_dir)
    model = learning.learned.model
    planned = PlanFile.load(run_dir)
    plan, weights = planned.plan, planned.sweep.weights
    replayed = ReplayFile.load(run_dir)
    _check_states(replayed, config, run_dir / layout.REPLAY)
    sweep = dict(zip(weights, planned.sweep.x, strict=True))
    clearance = dict(zip(weights, planned.sweep.clearance, strict=True))
    # the model's space (TP-GMM's frames where it learned in them) and the plan's
    frames = learning.learned.space if learning.learned.frames else None
    learned = task if frames is None else task.in_space(frames)
    labels, units = learned.dims, learned.space.units
    angle = int(learned.space.angles[0]) if learned.space.angles.size else 0  # Fig. 4's
    # name: (plots' function, its arguments); Fig. 8's snapshots rendered below
    drawings: dict[str, tuple[Any, ...]] = {
        "observation": (plots.plot_observation, observations, boundaries),
        "fig4_gmm_dtw": (
            partial(plots.plot_gmm_with_and_without_dtw, dim=angle, labels=labels, units=units),
            learning.raw, model,
        ),
        "fig5_bic": (plots.plot_bic_curves, {
            "fast (K-means only)": learning.bic_fast, "full (EM)": learning.bic_full,
        }),
        "gmr": (partial(plots.plot_gmr, labels=labels, units=units), model,
                list(learning.aligned)),
        "fig9_collision_sweep": (
            partial(plots.plot_collision_sweep, labels=task.dims, units=task.space.units,
                    position=task.space.positions[0]),
            plan.times, plan.mean,
            plan.variance, sweep, clearance, plan.weights,
        ),
        "costs": (plots.plot_costs, dict(zip(weights, planned.sweep.cost_total, strict=True))),
    }
    n_frames = 0

    def video(path: Path) -> None:
        nonlocal n_frames
        frames = _video_frames(config, replayed, observations, planned)
        n_frames = write_video(path, frames, config.video_fps)

    with drawing.worker() as worker:
        pngs = {name: worker.submit(plots.png, *draw) for name, draw in drawings.items()}
        try:
            pngs["fig8_snapshots"] = worker.submit(
                plots.png, plots.plot_snapshots, *_snapshots(config, replayed, planned)
            )
            write_atomic(run_dir / layout.VIDEO, video)
            for name in bar(layout.FIGURES, desc="figures", unit="figure"):
                save_bytes(run_dir / layout.figure(name), pngs[name].result())
        finally:
            for future in pngs.values():
                future.cancel()
    return {"video": {"frames": n_frames, "seconds": n_frames / config.video_fps}}


def _check_states(replayed: ReplayFile, config: RunConfig, path: Path) -> None:
    """Raise ``ImitateError`` unless the recorded states fit the run's scene (``(n, nq)``
    joint positions, ``(n, nmocap, 3)`` and ``(n, nmocap, 4)`` mocap poses), with the teacher
    mannequin if the replay had it (its mocap poses)."""
    recording = replayed.recording
    model = build_model(config.scene(teacher=recording.mocap_pos.shape[1] > 0))
    shapes = {"qpos": (model.nq,), "mocap_pos": (model.nmocap, 3), "mocap_quat": (model.nmocap, 4)}
    recorded = {**recording.states(), **{FREE + n: v for n, v in replayed.free.items()}}
    for name, states in recorded.items():
        found, wanted = states.shape, shapes[name.removeprefix(FREE)]
        if found[1:] != wanted:
            raise ImitateError(
                f"{path} holds {name} of shape {found}, not (n, {', '.join(map(str, wanted))}) "
                f"as the run's scene needs; re-run imitate replay"
            )


def _snapshots(config: RunConfig, replayed: ReplayFile, planned: PlanFile, n: int = 5):
    """Fig. 8's rows from the physics replays, the sweep's smallest collision weight's and the
    chosen one's: ``n`` snapshots each at the same plan times [s], one of them where the smallest
    weight's plan comes closest (collides); parts touching or penetrating are marked."""
    recording, sweep = replayed.recording, planned.sweep
    times = planned.plan.times - planned.plan.times[0]
    closest = times[np.argmin(sweep.clearance[0])]
    at = np.sort(np.r_[np.linspace(0.1, 0.9, n - 1) * times[-1], closest])
    index = np.round((at + recording.plan_start) / recording.state_dt).astype(int)
    index = np.minimum(index, len(recording.qpos) - 1)
    weights = (float(sweep.weights[0]), config.collision_weight)
    # both rows with one renderer (making one costs about as much as five snapshots on a CPU)
    states = recording.states()
    shown = {
        name: np.concatenate([replayed.free[name][index], states[name][index]]) for name in STATES
    }
    images = list(replay_frames(config.scene(), shown, *SNAPSHOT_SIZE, shadows=True, quick=True))
    marks = [_collision(d, pair) for d, pair in penetrations(config.scene(), shown)]
    rows = []
    for row, weight in enumerate(weights):
        cost = "without collision cost" if weight == 0 else "with collision cost"
        part = slice(row * len(index), (row + 1) * len(index))
        rows.append((f"{cost} (collision weight {weight:g})", images[part], marks[part]))
    return rows, at


def _collision(distance: float, pair: tuple[str, str]) -> str | None:
    """What Fig. 8 writes on a snapshot whose closest pair is ``distance`` [m] apart, if they
    touch: ``"collision: torso_chest / <tool>, 2.1 mm deep"``."""
    if distance >= TOUCHING_M:
        return None
    # A geom's name as a reader knows the part: <object>_hull_0 is the object.
    a, b = (re.sub(r"_(hull|wall)_\d+$", "", geom) for geom in pair)
    return f"collision: {a} / {b}, " + (
        f"{-1e3 * distance:.1f} mm deep" if distance < 0 else "touching"
    )


def _video_frames(
    config: RunConfig, replayed: ReplayFile, observations: Observations, planned: PlanFile
):
    """The teacher (the robot's eye view and its tracked objects inset), then the robot without
    the collision cost (the sweep's weight-0 plan, from its start until ``FREE_AFTER`` after it
    comes closest), then with it."""
    size = (config.video_width, config.video_height)
    motion = script_demonstrations(config.teacher())
    times = _teacher_times(
        motion.boundaries, motion.duration, config.teacher_speedup / config.video_fps,
        max(PAUSE_SPEEDUP, config.teacher_speedup) / config.video_fps,
    )
    tracks = observations.tracks
    teacher = captioned(
        teacher_frames(
            motion, times, *size, marks=_tracked_axes(tracks, times),
            projection=observations.projections[0], image_size=observations.image_size,
            threads=VIDEO_THREADS, quick=True,
        ),
        TEACHER_CAPTION.format(speedup=config.teacher_speedup),
    )
    times_planned = planned.plan.times
    closest = times_planned[np.argmin(planned.sweep.clearance[0])] - times_planned[0]
    recording = replayed.recording
    start, dt = recording.plan_start, recording.state_dt
    # the weight-0 part from the plan's start (the robot stands still before it, as the last
    # part shows), until FREE_AFTER after it comes closest
    shown = slice(int(round(start / dt)), int((start + closest + FREE_AFTER) / dt))
    free = len(replayed.free["qpos"][shown])
    # both robot parts in one sequence: their renderers are made once
    states = recording.states()
    robot = replay_frames(
        config.scene(),
        {name: np.concatenate([replayed.free[name][shown], states[name]]) for name in STATES},
        *size, threads=VIDEO_THREADS, quick=True,
    )
    parts = (
        teacher, captioned(itertools.islice(robot, free), FREE_CAPTION),
        captioned(robot, ROBOT_CAPTION.format(weight=config.collision_weight)),
    )
    total = len(times) + free + len(recording.qpos)
    return bar(itertools.chain(*parts), desc="video", unit="frame", total=total)


def _teacher_times(
    boundaries: np.ndarray, duration: float, step: float, pause_step: float
) -> np.ndarray:
    """The instants [s] of the teacher's frames: every ``step`` within the demonstrations
    (``boundaries``, ``(n, 2)`` [s]), every ``pause_step`` in the pauses between them."""
    times, t = [], 0.0
    while t < duration:
        times.append(t)
        moving = np.any((boundaries[:, 0] <= t) & (t < boundaries[:, 1]))
        t += step if moving else pause_step
    return np.array(times)


def _tracked_axes(tracks: Tracks, times: np.ndarray) -> np.ndarray:
    """The tracked objects' axes at ``times`` (the last frame at or before each), as segments
    ``(len(times), n_objects, 2, 3)`` [m] from bottom to top; NaN where not tracked."""
    k = np.clip(np.searchsorted(tracks.times, times, side="right") - 1, 0, len(tracks.times) - 1)
    half = np.array([objects.SHAPES[name].height / 2 for name in tracks.objects])[:, None, None]
    centre, axis = tracks.position[:, k], tracks.axis[:, k]  # (n_objects, len(times), 3)
    ends = np.stack([centre - half * axis, centre + half * axis], axis=2)
    return ends.transpose(1, 0, 2, 3)
