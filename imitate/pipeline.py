"""The stages of a run (see :mod:`imitate.stages`), from watching the teacher to pouring in physics.

Each stage reads the previous stage's artifacts in the run directory and writes its own
(atomically, see :mod:`imitate.artifacts`); :func:`run_stage` merges its numbers into
``report.json``. Every stage is a deterministic function of ``config.json`` and its inputs: the
same seed gives the same arrays and the same report (timings aside).
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import os
import re
import sys
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

import numpy as np
from tqdm import tqdm

from imitate import drawing, plots, provenance, report_html, stages
from imitate.artifacts import load_json, load_npz, save_json, save_npz, staged
from imitate.bic import bic_sweep
from imitate.config import RunConfig
from imitate.envs.observation import ObservationConfig
from imitate.envs.pouring import SUCCESS_FRACTION, PouringEnv
from imitate.envs.teacher_motion import script_demonstrations
from imitate.envs.video import (
    StateRecorder,
    captioned,
    penetrations,
    replay_frames,
    teacher_frames,
    write_video,
)
from imitate.errors import ImitateError
from imitate.learning import LearnedModel, LearningConfig
from imitate.learning import learn as learn_model
from imitate.metrics import demo_counts, tracking_errors
from imitate.models import humanoid, objects
from imitate.motion import Plan, PlanConfig, plan_from_model
from imitate.motion.metrics import deviation, pour_phase_error
from imitate.observe import observe as watch
from imitate.oracle import true_demos
from imitate.perception import Observations, Tracks, load_observations, save_observations
from imitate.pour_geometry import PourGeometry
from imitate.replay import planning_task
from imitate.replay import replay as replay_plan
from imitate.segment import StillnessConfig, load_demos, save_demos, segment, task_demo

__all__ = ["figures", "learn", "observe", "optimize", "replay", "run_stage"]

log = logging.getLogger(__name__)

APPROACH_S = 1.0  # [s] from the reset pose to the plan's start in the replay
STATE_NAMES = ("qpos", "mocap_pos", "mocap_quat")  # a recorded replay state (StateRecorder)
SNAPSHOT_SIZE = (480, 360)  # Fig. 8's panels [px]
TOUCHING_M = 1e-3  # closer than this, parts touch in physics (whose contacts keep them apart)
TEACHER_CAPTION = "teacher demonstrates ({speedup:g}x); inset: robot's eye, tracking"
ROBOT_CAPTION = "robot reproduces (collision weight {weight:g})"
FREE_CAPTION = "robot reproduces without the collision cost (weight 0): into its chest"
FREE_AFTER = 1.0  # [s] of the weight-0 replay shown after its plan comes closest

# Replays of the pour, each from its own seed of the initial-state noise; a run succeeds when the
# smallest of their pour fractions reaches SUCCESS_FRACTION (one replay's fraction is chaotic).
POUR_REPLAYS = 3


# --- Stages ------------------------------------------------------------------------------------


def observe(run_dir: Path, config: RunConfig) -> dict:
    """The teacher demonstrates, the robot's eyes track the objects, stillness cuts the demos."""
    watching = ObservationConfig(
        teacher=config.teacher(),
        fps=config.fps, width=config.width, height=config.height,
    )
    timing = {}
    progress = log.isEnabledFor(logging.INFO) and sys.stderr.isatty()
    observations = watch(watching, timing=timing, progress=progress)
    demos = segment(observations.tracks, StillnessConfig())
    save_observations(run_dir / "observations.npz", observations)
    save_demos(run_dir / "demos.npz", demos, observations.tracks)
    found = np.array([(d.start, d.end) for d in demos])
    return {
        "demos": demo_counts(found, observations.truth.boundaries),
        "perception": {
            **tracking_errors(observations),
            "render_pairs_per_s": timing["pairs"] / timing["render"],
            "track_pairs_per_s": timing["pairs"] / timing["track"],
        },
    }


def learn(run_dir: Path, config: RunConfig) -> dict:
    """Task space, DTW, GMM (components by BIC), GMR; the other BIC method for comparison."""
    if config.oracle:
        tracks = load_observations(run_dir / "observations.npz").tracks
        motion = script_demonstrations(config.teacher())
        demos, gaze, rate = true_demos(motion, tracks.gaze, tracks.times), tracks.gaze, config.fps
        bridged = 0
    else:
        segments, names, gaze = load_demos(run_dir / "demos.npz")
        bridged = sum(int(np.isnan(d.position).any(axis=-1).sum()) for d in segments)
        rate = 1.0 / float(np.median(np.diff(segments[0].times)))
        demos = [
            task_demo(d, names, gaze, smoothing=config.smoothing, rate=rate) for d in segments
        ]
    k_max = min(config.k_max, *(len(d) for d in demos))
    settings = LearningConfig(k_max=k_max, bic_method=config.bic, seed=config.seed)
    start = time.perf_counter()
    model = learn_model(demos, rate=rate, config=settings)
    seconds = time.perf_counter() - start
    other = "fast" if config.bic == "full" else "full"
    other_sweep = bic_sweep(model.data, k_max, other, config.seed)
    curves = {config.bic: model.bic_curve, other: other_sweep.curve}
    chosen = {config.bic: model.gmm.n_components, other: int(other_sweep.k)}
    raw = learn_model(
        demos, rate=rate,
        config=dataclasses.replace(settings, n_components=model.gmm.n_components, use_dtw=False),
    )
    save_npz(run_dir / "model.npz", {
        **model.to_arrays(), **raw.to_arrays("raw_"), "gaze": gaze, "rate": rate,
        "bic_fast": curves["fast"], "bic_full": curves["full"], "aligned": model.alignment.aligned,
    })
    return {
        "learning": {
            "source": "ground truth (oracle)" if config.oracle else "perception",
            "bic": config.bic,
            "n_components": model.gmm.n_components,
            "n_components_fast_bic": chosen["fast"],
            "n_components_full_bic": chosen["full"],
            "seconds": seconds,
            "bridged_samples": bridged,
        }
    }


def optimize(run_dir: Path, config: RunConfig) -> dict:
    """Whole-body attractor optimization at ``collision_weight``, and the Fig. 9 sweep."""
    arrays = load_npz(run_dir / "model.npz", required=(*LearnedModel.array_names(), "gaze"))
    model = LearnedModel.from_arrays(arrays)
    task = planning_task(config.scene(), arrays["gaze"])
    chosen = config.collision_weight
    weights = sorted({chosen * s for s in config.sweep} | {chosen})
    plans, seconds = {}, {}
    for w in tqdm(weights, desc="optimize", unit="plan", disable=_bars()):
        start = time.perf_counter()
        plans[w] = plan_from_model(
            task, model, q0=humanoid.rest_pose(),
            # the sweep shows the paper's optimizer, the attractors alone (Fig. 9)
            config=PlanConfig(
                collision_weight=w, max_iter=config.max_iter, nullspace_push=w == chosen,
                similarity=config.similarity, sigma_max_scale=config.sigma_max_scale,
            ),
        )
        seconds[w] = time.perf_counter() - start
    main = plans[chosen]
    save_npz(run_dir / "plan.npz", {
        **main.to_arrays(),
        "sweep_weights": np.array(weights),
        "sweep_x": np.array([plans[w].x for w in weights]),
        "sweep_q": np.array([plans[w].q for w in weights]),
        "sweep_clearance": np.array([_clearance(task, plans[w].q) for w in weights]),
        **{f"sweep{i}_cost_total": plans[w].costs["total"] for i, w in enumerate(weights)},
    })
    error_m, error_deg = pour_phase_error(main)
    first = plans[weights[0]]
    return {
        "optimization": {
            "collision_weight": chosen,
            "similarity": config.similarity,
            "sigma_max_scale": config.sigma_max_scale,
            "seconds": seconds[chosen],
            "iterations": main.n_iter,
            "converged": main.converged,
            "min_distance_m": main.min_distance,
            "closest_pair": list(main.closest or ()),
            "pour_phase_err_m": error_m,
            "pour_phase_err_deg": error_deg,
            "message": main.message,
            "sweep": [
                {"weight": w, "min_distance_m": plans[w].min_distance,
                 **deviation(plans[w], first)}
                for w in weights
            ],
        }
    }


def replay(run_dir: Path, config: RunConfig) -> dict:
    """The plan drives the robot's actuators in full physics, liquid and all; the pour again
    from ``POUR_REPLAYS - 1`` more seeds of the initial-state noise (it is chaotic). The plan of
    the sweep's smallest collision weight (Fig. 8's top row) too, recorded under ``sweep0_``.

    The replays are independent: they run in threads, one per core at most (MuJoCo's
    ``mj_step`` releases the GIL), each in its own env, so their results are those of a serial
    run."""
    jobs, gaze = _replay_jobs(run_dir, config)
    with (
        ThreadPoolExecutor(min(len(jobs), os.cpu_count() or 1)) as pool,
        tqdm(total=len(jobs), desc="replay", unit="replay", disable=_bars()) as bar,
    ):
        futures = [pool.submit(_physics, p, config, gaze, seed) for p, seed in jobs]
        for _ in as_completed(futures):
            bar.update()
        outcomes = [future.result() for future in futures]
    result, states, state_dt, geometry = outcomes[0]
    pours = [outcome[0].pour_fraction for outcome in outcomes[:POUR_REPLAYS]]
    free_states = outcomes[-1][1]
    save_npz(run_dir / "replay.npz", {
        **states, "task_error": result.task_error, "state_dt": state_dt,
        "pour_fraction": result.pour_fraction, "spilled": result.spilled,
        "min_distance": result.min_distance, "plan_start": APPROACH_S,
        **{f"sweep0_{name}": value for name, value in free_states.items()},
    })
    return {
        "replay": {
            "pour_fraction": result.pour_fraction,
            "spilled": result.spilled,
            "min_distance_m": result.min_distance,
            "task_err_m_max": float(np.linalg.norm(result.task_error[:, :3], axis=1).max()),
            "pour_fraction_mean": float(np.mean(pours)),
            "pour_fraction_min": float(np.min(pours)),
            "pour_fractions": pours,
            "success": bool(min(pours) >= SUCCESS_FRACTION and result.min_distance >= 0.0),
            "pour_geometry": geometry,
        }
    }


def figures(run_dir: Path, config: RunConfig) -> dict:
    """The figures (``figures/*.png``) and the video: the teacher, then the robot pouring.

    A worker process (:mod:`imitate.drawing`) draws the figures while this one renders and
    encodes the video."""
    observations = load_observations(run_dir / "observations.npz")
    boundaries = load_npz(run_dir / "demos.npz", required=("boundaries",))["boundaries"]
    arrays = load_npz(run_dir / "model.npz", required=(
        *LearnedModel.array_names(), *LearnedModel.array_names("raw_"), "bic_fast", "bic_full",
    ))
    model, raw = LearnedModel.from_arrays(arrays), LearnedModel.from_arrays(arrays, "raw_")
    plan = load_npz(run_dir / "plan.npz", required=(
        "times", "mean", "variance", "weights", "sweep_weights", "sweep_x", "sweep_clearance",
    ))
    states = load_npz(run_dir / "replay.npz", required=(
        *STATE_NAMES, *(f"sweep0_{name}" for name in STATE_NAMES), "state_dt", "plan_start",
    ))
    weights = plan["sweep_weights"]
    sweep = dict(zip(weights, plan["sweep_x"], strict=True))
    clearance = dict(zip(weights, plan["sweep_clearance"], strict=True))
    drawings = {  # name: (plots' function, its arguments); Fig. 8's snapshots rendered below
        "observation": (plots.plot_observation, observations, boundaries),
        "fig4_gmm_dtw": (plots.plot_gmm_with_and_without_dtw, raw, model),
        "fig5_bic": (plots.plot_bic_curves, {
            "fast (K-means only)": arrays["bic_fast"], "full (EM)": arrays["bic_full"],
        }),
        "gmr": (plots.plot_gmr, model, list(arrays["aligned"])),
        "fig9_collision_sweep": (
            plots.plot_collision_sweep, plan["times"], plan["mean"], plan["variance"], sweep,
            clearance, plan["weights"],
        ),
        "costs": (
            plots.plot_costs, {w: plan[f"sweep{i}_cost_total"] for i, w in enumerate(weights)}
        ),
    }
    with drawing.worker() as worker:
        pngs = {name: worker.submit(plots.png, *draw) for name, draw in drawings.items()}
        try:
            pngs["fig8_snapshots"] = worker.submit(
                plots.png, plots.plot_snapshots, *_snapshots(config, states, plan)
            )
            n_frames = write_video(
                run_dir / "video.mp4", _video_frames(config, states, observations, plan),
                config.video_fps,
            )
            for name in tqdm(stages.FIGURES, desc="figures", unit="figure", disable=_bars()):
                plots.save_png(pngs[name].result(), run_dir / "figures" / f"{name}.png")
        finally:
            for future in pngs.values():
                future.cancel()
    return {"video": {"frames": n_frames, "seconds": n_frames / config.video_fps}}


# --- Running -----------------------------------------------------------------------------------


def run_stage(stage: str, run_dir: Path, config: RunConfig, force: bool = False) -> dict:
    """Run one stage in ``run_dir`` with ``config``, all or nothing: its artifacts,
    ``config.json``, its record in ``manifest.json`` (see :mod:`imitate.provenance`),
    ``report.json`` (its numbers, its time and the artifacts present merged in; the sections of
    later stages dropped, as they no longer follow from it) and ``report.html`` (the same as a
    page, see :mod:`imitate.report_html`) are renamed into place only when the stage has
    succeeded. Returns the report.

    Raises:
        ImitateError: before the stage runs, ``report.json`` or ``manifest.json`` is unusable,
            or an input is stale or from another run (with ``force``: a warning on stderr
            instead); or the stage's own errors. The directory is then unchanged.
    """
    current = stages.find(stage)
    run_dir = Path(run_dir)
    previous = _previous_report(run_dir)
    manifest = provenance.load(run_dir)
    problems = provenance.stale(run_dir, current, config, manifest)
    if problems and not force:
        raise ImitateError(f"{problems[0]}, or add --force to go on anyway")
    for problem in problems:
        log.warning("%s; going on anyway (--force)", problem)
    with staged(run_dir) as staging:
        start = time.perf_counter()
        sections = current.run(run_dir, config)
        seconds = time.perf_counter() - start
        outputs = staging.files()
        manifest = provenance.recorded(manifest, run_dir, current, config, outputs)
        report = _report(current, sections, seconds, previous, config.seed)
        report["artifacts"] = _artifacts(run_dir, set(outputs))
        save_json(run_dir / "config.json", config.to_json())
        save_json(run_dir / provenance.MANIFEST, manifest)
        save_json(run_dir / stages.REPORT, report)
        report_html.save_run_page(run_dir, report, config.to_json())
    log.debug("%s wrote %s in %.1f s", stage, ", ".join(sorted(outputs)), seconds)
    return report


# --- Helpers -----------------------------------------------------------------------------------


def _replay_jobs(run_dir: Path, config: RunConfig) -> tuple[list[tuple[Plan, int]], np.ndarray]:
    """The replay stage's replays as (plan, seed): the plan from ``POUR_REPLAYS`` seeds, then the
    sweep's smallest collision weight's plan; and the learned gaze ``(3, 3)``."""
    arrays = load_npz(run_dir / "plan.npz", required=(*Plan.array_names(), "sweep_q", "sweep_x"))
    plan = Plan.from_arrays(arrays)
    gaze = load_npz(run_dir / "model.npz", required=("gaze",))["gaze"]
    q_free = arrays["sweep_q"][0]
    free = dataclasses.replace(
        plan, q=q_free, q_start=q_free[0], approach_bend=np.zeros_like(q_free[0]),
        x=arrays["sweep_x"][0],
    )
    return [(plan, config.seed + k) for k in range(POUR_REPLAYS)] + [(free, config.seed)], gaze


def _physics(plan: Plan, config: RunConfig, gaze: np.ndarray, seed: int):
    """``plan`` replayed in a fresh ``PouringEnv`` from ``seed``: the result, the recorded
    states (:meth:`StateRecorder.arrays`), their spacing [s] and where the stream met the glass
    (:meth:`PourGeometry.summary`)."""
    env = PouringEnv(particles=config.particles, obstacles=config.scene().obstacles)
    recorder = StateRecorder(every=max(1, round(1.0 / (config.video_fps * env.dt))))
    geometry = PourGeometry()

    def step(env: PouringEnv) -> None:
        recorder(env)
        geometry(env)

    options = {"bottle_grasp": config.bottle_grasp, "glass_grasp": config.glass_grasp}
    result = replay_plan(
        plan, env, seed=seed, approach=APPROACH_S, options=options, on_step=step, gaze=gaze,
    )
    env.close()
    return result, recorder.arrays(), recorder.every * env.dt, geometry.summary()


def _clearance(task, q: np.ndarray) -> np.ndarray:
    """Smallest signed distance [m] between the robot, the objects and the scene at each step of
    the joint trajectory ``q`` ``(T + 1, n)``; ``(T + 1,)``, negative when penetrating."""
    distances = []
    for q_t in q:
        task.kin.update(q_t)
        distances.append(task.kin.min_distance()[0])
    return np.array(distances)


def _snapshots(config: RunConfig, states: dict[str, np.ndarray], plan: dict, n: int = 5):
    """Fig. 8's rows from the physics replays, the sweep's smallest collision weight's and the
    chosen one's: ``n`` snapshots each at the same plan times [s], one of them where the smallest
    weight's plan comes closest (collides); parts touching or penetrating are marked."""
    times = plan["times"] - plan["times"][0]
    closest = times[np.argmin(plan["sweep_clearance"][0])]
    at = np.sort(np.r_[np.linspace(0.1, 0.9, n - 1) * times[-1], closest])
    index = np.round((at + float(states["plan_start"])) / float(states["state_dt"])).astype(int)
    index = np.minimum(index, len(states["qpos"]) - 1)
    lowest = float(plan["sweep_weights"][0])
    rows = []
    for prefix, weight in (("sweep0_", lowest), ("", config.collision_weight)):
        shown = {name: states[prefix + name][index] for name in STATE_NAMES}
        images = list(replay_frames(config.scene(), shown, *SNAPSHOT_SIZE, shadows=True))
        marks = [_collision(d, pair) for d, pair in penetrations(config.scene(), shown)]
        cost = "without collision cost" if weight == 0 else "with collision cost"
        rows.append((f"{cost} (collision weight {weight:g})", images, marks))
    return rows, at


def _collision(distance: float, pair: tuple[str, str]) -> str | None:
    """What Fig. 8 writes on a snapshot whose closest pair is ``distance`` [m] apart, if they
    touch: ``"collision: torso_chest / bottle, 2.1 mm deep"``."""
    if distance >= TOUCHING_M:
        return None
    # A geom's name as a reader knows the part: bottle_hull_0 is the bottle.
    a, b = (re.sub(r"_(hull|wall)_\d+$", "", geom) for geom in pair)
    return f"collision: {a} / {b}, " + (
        f"{-1e3 * distance:.1f} mm deep" if distance < 0 else "touching"
    )


# The video's frames render in two threads at once, each with its own renderer: one kept about
# 1.6 of the 2-core CPU's cores busy (Mesa). More do not pay on a GPU: on an H100 machine (16
# cores) the frames took 2.3 s in one thread, 2.1 s in two and 10.8 s in four.
VIDEO_THREADS = 2


def _video_frames(
    config: RunConfig, states: dict[str, np.ndarray], observations: Observations, plan: dict
):
    """The teacher (the robot's eye view and its tracked objects inset), then the robot without
    the collision cost (the sweep's weight-0 plan, until ``FREE_AFTER`` after it comes closest),
    then with it."""
    size = (config.video_width, config.video_height)
    motion = script_demonstrations(config.teacher())
    times = np.arange(0.0, motion.duration, config.teacher_speedup / config.video_fps)
    tracks = observations.tracks
    teacher = captioned(
        teacher_frames(
            motion, times, *size, marks=_tracked_axes(tracks, times),
            projection=observations.projections[0], image_size=observations.image_size,
            threads=VIDEO_THREADS,
        ),
        TEACHER_CAPTION.format(speedup=config.teacher_speedup),
    )
    closest = plan["times"][np.argmin(plan["sweep_clearance"][0])] - plan["times"][0]
    free = int((float(states["plan_start"]) + closest + FREE_AFTER) / float(states["state_dt"]))
    robot = [
        captioned(
            replay_frames(
                config.scene(), {name: states[prefix + name][:end] for name in STATE_NAMES},
                *size, threads=VIDEO_THREADS,
            ),
            caption,
        )
        for prefix, caption, end in (
            ("sweep0_", FREE_CAPTION, free),
            ("", ROBOT_CAPTION.format(weight=config.collision_weight), None),
        )
    ]
    total = len(times) + len(states["sweep0_qpos"][:free]) + len(states["qpos"])
    return tqdm(
        itertools.chain(teacher, *robot), desc="video", unit="frame", total=total,
        disable=_bars(),
    )


def _bars() -> bool | None:
    """tqdm's ``disable``: progress bars on a terminal (None), none below INFO (``-q``)."""
    return None if log.isEnabledFor(logging.INFO) else True


def _report(
    current: stages.Stage, sections: dict, seconds: float, previous: dict, seed: int
) -> dict:
    """The report after ``current`` returned ``sections`` in ``seconds`` [s]: those of the
    earlier stages kept from ``previous``, those of later ones dropped."""
    earlier = stages.STAGES[: stages.STAGES.index(current)]
    kept = {name for s in earlier for name in s.sections}
    report = {"schema": stages.REPORT_SCHEMA, "seed": seed}
    for name in [name for s in stages.STAGES for name in s.sections]:
        if name in sections:
            report[name] = sections[name]
        elif name in kept and name in previous:
            report[name] = previous[name]
    done = {s.name for s in earlier}
    timings = {s: t for s, t in previous.get("timings", {}).items() if s in done}
    report["timings"] = {**timings, current.name: seconds}
    return report


def _tracked_axes(tracks: Tracks, times: np.ndarray) -> np.ndarray:
    """The tracked objects' axes at ``times`` (the last frame at or before each), as segments
    ``(len(times), n_objects, 2, 3)`` [m] from bottom to top; NaN where not tracked."""
    k = np.clip(np.searchsorted(tracks.times, times, side="right") - 1, 0, len(tracks.times) - 1)
    half = np.array([objects.SHAPES[name].height / 2 for name in tracks.objects])[:, None, None]
    centre, axis = tracks.position[:, k], tracks.axis[:, k]  # (n_objects, len(times), 3)
    ends = np.stack([centre - half * axis, centre + half * axis], axis=2)
    return ends.transpose(1, 0, 2, 3)


def _previous_report(run_dir: Path) -> dict:
    """``report.json`` of ``run_dir`` (empty if none yet).

    Raises:
        ImitateError: it is unreadable, or not an object of sections.
    """
    path = run_dir / stages.REPORT
    if not path.exists():
        return {}
    report = load_json(path)
    names = ("timings", *(name for s in stages.STAGES for name in s.sections))
    if not isinstance(report, dict) or any(
        not isinstance(report.get(name, {}), dict) for name in names
    ):
        raise ImitateError(
            f"{path} is not a report (an object of sections); delete it to start a new report"
        )
    return report


def _artifacts(run_dir: Path, written: set[str]) -> dict[str, str]:
    """Relative paths of the artifacts present or ``written`` now, by name (the report:
    always)."""
    report = stages.REPORT
    names = (*(name for s in stages.STAGES for name in s.writes), report)
    return {
        Path(name).stem: name
        for name in names
        if name in written or (run_dir / name).exists() or name == report
    }
