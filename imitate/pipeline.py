"""The stages of a run (see :mod:`imitate.stages`), from watching the teacher to pouring in physics.

Each stage reads the previous stage's artifacts in the run directory and writes its own
(atomically, see :mod:`imitate.artifacts`); :func:`run_stage` merges its numbers into
``report.json``. Every stage is a deterministic function of ``config.json`` and its inputs: the
same seed gives the same arrays and the same report (timings aside).
"""

from __future__ import annotations

import dataclasses
import itertools
import sys
import time
from pathlib import Path

import numpy as np
from tqdm import tqdm

from imitate import plots, provenance, stages
from imitate.artifacts import load_json, load_npz, save_json, save_npz, staged
from imitate.bic import bic_sweep
from imitate.config import RunConfig
from imitate.envs.observation import ObservationConfig
from imitate.envs.pouring import PouringEnv
from imitate.envs.teacher_motion import script_demonstrations
from imitate.envs.video import (
    StateRecorder,
    captioned,
    close_up,
    replay_frames,
    teacher_frames,
    write_video,
)
from imitate.errors import ImitateError
from imitate.learning import LearnedModel, LearningConfig
from imitate.learning import learn as learn_model
from imitate.metrics import demo_counts, tracking_errors
from imitate.models import humanoid
from imitate.motion import Plan, PlanConfig, plan_from_model
from imitate.motion.metrics import deviation, pour_phase_error
from imitate.observe import observe as watch
from imitate.oracle import true_demos
from imitate.perception import load_observations, save_observations
from imitate.replay import planning_task
from imitate.replay import replay as replay_plan
from imitate.segment import StillnessConfig, load_demos, save_demos, segment, task_demo
from imitate.warmup import announce_compiles

__all__ = ["figures", "learn", "observe", "optimize", "replay", "run_stage"]


# --- Stages ------------------------------------------------------------------------------------


def observe(run_dir: Path, config: RunConfig) -> dict:
    """The teacher demonstrates, the robot's eyes track the objects, stillness cuts the demos."""
    watching = ObservationConfig(
        teacher=config.teacher(),
        fps=config.fps, width=config.width, height=config.height,
    )
    timing = {}
    observations = watch(watching, timing=timing, progress=sys.stderr.isatty())
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
    """Whole-body attractor optimisation at ``collision_weight``, and the Fig. 9 sweep."""
    arrays = load_npz(run_dir / "model.npz", required=(*LearnedModel.array_names(), "gaze"))
    model = LearnedModel.from_arrays(arrays)
    task = planning_task(config.scene(), arrays["gaze"])
    chosen = config.collision_weight
    weights = sorted({chosen * s for s in config.sweep} | {chosen})
    plans, seconds = {}, {}
    for w in tqdm(weights, desc="optimize", unit="plan", disable=None):
        start = time.perf_counter()
        plans[w] = plan_from_model(
            task, model, q0=humanoid.rest_pose(),
            config=PlanConfig(collision_weight=w, max_iter=config.max_iter),
        )
        seconds[w] = time.perf_counter() - start
    main = plans[chosen]
    save_npz(run_dir / "plan.npz", {
        **main.to_arrays(),
        "sweep_weights": np.array(weights),
        "sweep_x": np.array([plans[w].x for w in weights]),
        **{f"sweep{i}_cost_total": plans[w].costs["total"] for i, w in enumerate(weights)},
    })
    error_m, error_deg = pour_phase_error(main)
    first = plans[weights[0]]
    return {
        "optimization": {
            "collision_weight": chosen,
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
    """The plan drives the robot's actuators in full physics, liquid and all."""
    plan = Plan.from_arrays(load_npz(run_dir / "plan.npz", required=Plan.array_names()))
    env = PouringEnv(particles=config.particles, obstacles=config.scene().obstacles)
    recorder = StateRecorder(every=max(1, round(1.0 / (config.video_fps * env.dt))))
    options = {"bottle_grasp": config.bottle_grasp, "glass_grasp": config.glass_grasp}
    gaze = load_npz(run_dir / "model.npz", required=("gaze",))["gaze"]
    result = replay_plan(
        plan, env, seed=config.seed, options=options, on_step=recorder, gaze=gaze
    )
    env.close()
    states = recorder.arrays()
    save_npz(run_dir / "replay.npz", {
        **states, "task_error": result.task_error, "state_dt": recorder.every * env.dt,
        "pour_fraction": result.pour_fraction, "spilled": result.spilled,
        "min_distance": result.min_distance,
    })
    return {
        "replay": {
            "pour_fraction": result.pour_fraction,
            "spilled": result.spilled,
            "min_distance_m": result.min_distance,
            "task_err_m_max": float(np.linalg.norm(result.task_error[:, :3], axis=1).max()),
            "success": bool(result.is_success and result.min_distance >= 0.0),
        }
    }


def figures(run_dir: Path, config: RunConfig) -> dict:
    """The figures (``figures/*.png``) and the video: the teacher, then the robot pouring."""
    observations = load_observations(run_dir / "observations.npz")
    boundaries = load_npz(run_dir / "demos.npz", required=("boundaries",))["boundaries"]
    arrays = load_npz(run_dir / "model.npz", required=(
        *LearnedModel.array_names(), *LearnedModel.array_names("raw_"), "bic_fast", "bic_full",
    ))
    model, raw = LearnedModel.from_arrays(arrays), LearnedModel.from_arrays(arrays, "raw_")
    plan = load_npz(
        run_dir / "plan.npz", required=("times", "mean", "variance", "sweep_weights", "sweep_x")
    )
    states = load_npz(
        run_dir / "replay.npz", required=("qpos", "mocap_pos", "mocap_quat", "state_dt")
    )
    weights = plan["sweep_weights"]
    sweep = dict(zip(weights, plan["sweep_x"], strict=True))
    drawings = {
        "observation": lambda: plots.plot_observation(observations, boundaries),
        "fig4_gmm_dtw": lambda: plots.plot_gmm_with_and_without_dtw(raw, model),
        "fig5_bic": lambda: plots.plot_bic_curves(
            {"fast (K-means only)": arrays["bic_fast"], "full (EM)": arrays["bic_full"]}
        ),
        "gmr": lambda: plots.plot_gmr(model, list(arrays["aligned"])),
        "fig8_snapshots": lambda: plots.plot_snapshots(*_snapshots(config, states)),
        "fig9_collision_sweep": lambda: plots.plot_collision_sweep(
            plan["times"], plan["mean"], plan["variance"], sweep
        ),
        "costs": lambda: plots.plot_costs(
            {w: plan[f"sweep{i}_cost_total"] for i, w in enumerate(weights)}
        ),
    }
    for name in tqdm(stages.FIGURES, desc="figures", unit="figure", disable=None):
        plots.save(drawings[name](), run_dir / "figures" / f"{name}.png")
    n_frames = write_video(run_dir / "video.mp4", _video_frames(config, states), config.video_fps)
    return {"video": {"frames": n_frames, "seconds": n_frames / config.video_fps}}


# --- Running -----------------------------------------------------------------------------------


def run_stage(stage: str, run_dir: Path, config: RunConfig, force: bool = False) -> dict:
    """Run one stage in ``run_dir`` with ``config``, all or nothing: its artifacts,
    ``config.json``, its record in ``manifest.json`` (see :mod:`imitate.provenance`) and
    ``report.json`` (its numbers, its time and the artifacts present merged in; the sections of
    later stages dropped, as they no longer follow from it) are renamed into place only when
    the stage has succeeded. Returns the report.

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
        print(f"warning: {problem}; going on anyway (--force)", file=sys.stderr)
    if sys.stderr.isatty():  # as the progress bars: a kernel numba compiles says so
        announce_compiles()
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
    return report


# --- Helpers -----------------------------------------------------------------------------------


def _snapshots(config: RunConfig, states: dict[str, np.ndarray], n: int = 6):
    """``n`` close-up images over the replay and their times [s]."""
    index = np.linspace(0, len(states["qpos"]) - 1, n + 2).round().astype(int)[1:-1]
    chosen = {name: states[name][index] for name in ("qpos", "mocap_pos", "mocap_quat")}
    images = list(replay_frames(config.scene(), chosen, 400, 300, close_up(), shadows=True))
    return images, index * float(states["state_dt"])


def _video_frames(config: RunConfig, states: dict[str, np.ndarray]):
    size = (config.video_width, config.video_height)
    motion = script_demonstrations(config.teacher())
    times = np.arange(0.0, motion.duration, config.teacher_speedup / config.video_fps)
    teacher = captioned(
        teacher_frames(motion, times, *size), f"teacher demonstrates ({config.teacher_speedup:g}x)"
    )
    robot = captioned(
        replay_frames(config.scene(), states, *size),
        f"robot reproduces (collision weight {config.collision_weight:g})",
    )
    total = len(times) + len(states["qpos"])
    return tqdm(
        itertools.chain(teacher, robot), desc="video", unit="frame", total=total, disable=None
    )


def _report(
    current: stages.Stage, sections: dict, seconds: float, previous: dict, seed: int
) -> dict:
    """The report after ``current`` returned ``sections`` in ``seconds`` [s]: those of the
    earlier stages kept from ``previous``, those of later ones dropped."""
    earlier = stages.STAGES[: stages.STAGES.index(current)]
    kept = {name for s in earlier for name in s.sections}
    report = {"seed": seed}
    for name in [name for s in stages.STAGES for name in s.sections]:
        if name in sections:
            report[name] = sections[name]
        elif name in kept and name in previous:
            report[name] = previous[name]
    done = {s.name for s in earlier}
    timings = {s: t for s, t in previous.get("timings", {}).items() if s in done}
    report["timings"] = {**timings, current.name: seconds}
    return report


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
