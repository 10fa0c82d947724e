"""The stages of a run, from watching the teacher to pouring in physics, and their artifacts.

Each stage reads the previous stage's files in the run directory and writes its own (atomically,
see :mod:`imitate.artifacts`), then merges its numbers into ``report.json``:

=========  ===========================================  ========================================
stage      reads                                        writes
=========  ===========================================  ========================================
observe    ``config.json``                              ``observations.npz``, ``demos.npz``
learn      ``demos.npz`` (``observations.npz``: oracle)  ``model.npz``
optimize   ``model.npz``                                ``plan.npz``
replay     ``plan.npz``                                 ``replay.npz``
figures    all of the above                             ``figures/*.png``, ``video.mp4``
=========  ===========================================  ========================================

Every stage is a deterministic function of ``config.json`` and its inputs: the same seed gives
the same arrays and the same report (timings aside).
"""

from __future__ import annotations

import dataclasses
import itertools
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from scipy.signal import savgol_filter
from tqdm import tqdm

from imitate import plots
from imitate.artifacts import load_json, load_npz, save_json, save_npz
from imitate.bic import BIC_METHODS, bic_sweep
from imitate.envs import assembly
from imitate.envs.observation import ObservationConfig
from imitate.envs.pouring import PouringEnv
from imitate.envs.teacher_motion import TeacherConfig, script_demonstrations
from imitate.envs.video import (
    StateRecorder,
    captioned,
    close_up,
    replay_frames,
    teacher_frames,
    write_video,
)
from imitate.errors import ImitateError
from imitate.gmm import GMM
from imitate.learning import LearnedModel, LearningConfig
from imitate.learning import learn as learn_model
from imitate.models import humanoid, objects
from imitate.motion import Plan, PlanConfig, TaskMap
from imitate.motion import plan as optimise
from imitate.observe import observe as watch
from imitate.perception import Observations, load_observations, save_observations
from imitate.replay import planning_task
from imitate.replay import replay as replay_plan
from imitate.segment import StillnessConfig, load_demos, save_demos, segment
from imitate.taskspace import task_space

__all__ = ["STAGES", "RunConfig", "load_config", "run_stage"]

STAGES = ("observe", "learn", "optimize", "replay", "figures")
_HEIGHTS = {objects.BOTTLE: objects.BOTTLE_SHAPE.height, objects.GLASS: objects.GLASS_SHAPE.height}
_FIGURES = (
    "observation", "fig4_gmm_dtw", "fig5_bic", "gmr", "fig8_snapshots", "fig9_collision_sweep",
    "costs",
)


@dataclass(frozen=True)
class RunConfig:
    """Everything a run depends on; stored as ``config.json`` in the run directory.

    Attributes:
        seed: Seed of the teacher's demonstrations, the K-means starts and the replay's reset.
        n_demos: Demonstrations the teacher shows, 2..20.
        width, height: Head-camera image size [px], 64..1920 by 48..1080.
        fps: Camera rate [Hz], 5..120.
        oracle: Learn from the ground-truth object poses instead of the tracked ones.
        smoothing: Savitzky-Golay window over the tracked positions and axes before learning
            [s], 0..1 (0: none; the segmentation's window by default).
        k_max: Largest number of GMM components of the BIC sweep, 1..50.
        bic: How the number of components is chosen: ``"full"`` (EM for every K; the default:
            on tracked demonstrations the paper's ``"fast"`` K-means heuristic tends to choose
            fewer components, and too few attractors smooth the movement away) or ``"fast"``.
        collision_weight: Weight of the collision cost of the optimiser, >= 0.
        sweep: Collision weights of the Fig. 9 sweep, as fractions of ``collision_weight``.
        max_iter: Optimiser iteration limit, >= 1.
        obstacle: A box or cylinder on the table, or ``None``.
        bottle_grasp, glass_grasp: Heights at which the robot holds the objects [m].
        particles: Liquid spheres in the bottle, 1..120.
        video_width, video_height: Size of ``video.mp4`` [px].
        video_fps: Frame rate of ``video.mp4`` [Hz].
        teacher_speedup: The teacher's part of the video plays this many times faster, >= 1.
    """

    seed: int = 0
    n_demos: int = 5
    width: int = 640
    height: int = 480
    fps: float = 30.0
    oracle: bool = False
    smoothing: float = StillnessConfig.smoothing
    k_max: int = 30
    bic: str = "full"
    collision_weight: float = PlanConfig.collision_weight
    sweep: tuple[float, ...] = (0.0, 0.1, 1.0)
    max_iter: int = PlanConfig.max_iter
    obstacle: assembly.Obstacle | None = None
    bottle_grasp: float = assembly.SceneConfig.bottle_grasp
    glass_grasp: float = assembly.SceneConfig.glass_grasp
    particles: int = 60
    video_width: int = 640
    video_height: int = 480
    video_fps: float = 25.0
    teacher_speedup: float = 2.0

    def __post_init__(self):
        if isinstance(self.obstacle, dict):  # from config.json
            values = {k: tuple(v) if isinstance(v, list) else v for k, v in self.obstacle.items()}
            object.__setattr__(self, "obstacle", assembly.Obstacle(**values))
        object.__setattr__(self, "sweep", tuple(float(s) for s in self.sweep))
        for name, low, high in (
            ("n_demos", 2, 20),
            ("width", 64, 1920),
            ("height", 48, 1080),
            ("fps", 5, 120),
            ("smoothing", 0, 1),
            ("k_max", 1, 50),
            ("max_iter", 1, 10_000),
            ("particles", 1, assembly.MAX_PARTICLES),
            ("video_width", 64, 1920),
            ("video_height", 48, 1080),
            ("video_fps", 1, 60),
            ("teacher_speedup", 1, 10),
        ):
            value = getattr(self, name)
            if not low <= value <= high:
                raise ImitateError(f"{name}={value!r} not accepted: a value in {low}..{high}")
        if not (np.isfinite(self.collision_weight) and self.collision_weight >= 0):
            raise ImitateError(
                f"collision_weight={self.collision_weight!r} not accepted: a finite value >= 0"
            )
        if self.bic not in BIC_METHODS:
            raise ImitateError(f"bic={self.bic!r} not accepted: one of {BIC_METHODS}")
        if not self.sweep or min(self.sweep) < 0:
            raise ImitateError(f"sweep={self.sweep!r} not accepted: fractions >= 0")
        self.scene()  # validates the grasps and the obstacle

    @classmethod
    def quick(cls, **overrides) -> RunConfig:
        """Small images, 3 demonstrations, short optimisation: the whole run in well under
        a minute (for tests)."""
        settings = dict(
            n_demos=3, width=320, height=240, fps=20.0, k_max=10, max_iter=30, particles=30,
            video_width=320, video_height=240, video_fps=10.0, teacher_speedup=3.0,
        )
        return cls(**{**settings, **overrides})

    def scene(self, **overrides) -> assembly.SceneConfig:
        """The robot's scene (objects in its hands)."""
        settings = dict(
            particles=self.particles,
            obstacles=(self.obstacle,) if self.obstacle else (),
            bottle_grasp=self.bottle_grasp,
            glass_grasp=self.glass_grasp,
        )
        return assembly.SceneConfig(**{**settings, **overrides})

    def to_json(self) -> dict[str, Any]:
        """The settings as JSON-ready values (the obstacle as a dict)."""
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, values: dict[str, Any]) -> RunConfig:
        """Settings read back from ``config.json``; unknown names are refused."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(values) - names)
        if unknown:
            raise ImitateError(
                f"config.json has unknown settings {unknown}; accepted: {sorted(names)}"
            )
        return cls(**values)


# --- Stages ------------------------------------------------------------------------------------


def observe(run_dir: Path, config: RunConfig) -> dict:
    """The teacher demonstrates, the robot's eyes track the objects, stillness cuts the demos."""
    watching = ObservationConfig(
        teacher=TeacherConfig(n_demos=config.n_demos, seed=config.seed),
        fps=config.fps, width=config.width, height=config.height,
    )
    timing = {}
    observations = watch(watching, timing=timing, progress=sys.stderr.isatty())
    demos = segment(observations.tracks, StillnessConfig())
    save_observations(run_dir / "observations.npz", observations)
    save_demos(run_dir / "demos.npz", demos, observations.tracks)
    found = np.array([(d.start, d.end) for d in demos])
    return {
        "demos": _demo_counts(found, observations.truth.boundaries),
        "perception": {
            **_tracking_errors(observations),
            "render_pairs_per_s": timing["pairs"] / timing["render"],
            "track_pairs_per_s": timing["pairs"] / timing["track"],
        },
    }


def learn(run_dir: Path, config: RunConfig) -> dict:
    """Task space, DTW, GMM (components by BIC), GMR; the other BIC method for comparison."""
    if config.oracle:
        observations = load_observations(run_dir / "observations.npz")
        demos, gaze, rate = _true_demos(observations), observations.tracks.gaze, config.fps
        bridged = 0
    else:
        segments, names, gaze = load_demos(run_dir / "demos.npz")
        bridged = sum(int(np.isnan(d.position).any(axis=-1).sum()) for d in segments)
        rate = 1.0 / float(np.median(np.diff(segments[0].times)))
        frames = int(round(config.smoothing * rate)) | 1
        demos = [
            _task_demo(*_smoothed(*_bridged(d.times, d.position, d.axis), frames), names, gaze)
            for d in segments
        ]
    k_max = min(config.k_max, *(len(d) for d in demos))
    settings = LearningConfig(k_max=k_max, bic_method=config.bic, seed=config.seed)
    start = time.perf_counter()
    model = learn_model(demos, rate=rate, config=settings)
    seconds = time.perf_counter() - start
    other = "fast" if config.bic == "full" else "full"
    other_sweep = bic_sweep(model.data, k_max, other, config.seed)
    k_other, other_curve = other_sweep.k, other_sweep.curve
    curves = {config.bic: model.bic_curve, other: other_curve}
    chosen = {config.bic: model.gmm.n_components, other: int(k_other)}
    raw = learn_model(
        demos, rate=rate,
        config=dataclasses.replace(settings, n_components=model.gmm.n_components, use_dtw=False),
    )
    save_npz(run_dir / "model.npz", {
        **_model_arrays(model, ""), **_model_arrays(raw, "raw_"), "gaze": gaze, "rate": rate,
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
    model = load_npz(run_dir / "model.npz", required=("times", "mean", "covariance", "gaze"))
    task = _task_map(config, model["gaze"])
    chosen = config.collision_weight
    weights = sorted({chosen * s for s in config.sweep} | {chosen})
    plans, seconds = {}, {}
    for w in tqdm(weights, desc="optimize", unit="plan", disable=None):
        start = time.perf_counter()
        plans[w] = _plan(task, model, config, w)
        seconds[w] = time.perf_counter() - start
    main = plans[chosen]
    save_npz(run_dir / "plan.npz", {
        **_plan_arrays(main),
        "sweep_weights": np.array(weights),
        "sweep_x": np.array([plans[w].x for w in weights]),
        **{f"sweep{i}_cost_total": plans[w].costs["total"] for i, w in enumerate(weights)},
    })
    error = main.task_error()[pour_phase(main.mean)]
    zero = plans[weights[0]]
    return {
        "optimization": {
            "collision_weight": chosen,
            "seconds": seconds[chosen],
            "iterations": main.n_iter,
            "converged": main.converged,
            "min_distance_m": main.min_distance,
            "closest_pair": list(main.closest or ()),
            "pour_phase_err_m": float(np.linalg.norm(error[:, :3], axis=1).max()),
            "pour_phase_err_deg": float(np.degrees(np.abs(error[:, [3, 5]]).max())),
            "message": main.message,
            "sweep": [_deviation(plans[w], zero, w) for w in weights],
        }
    }


def replay(run_dir: Path, config: RunConfig) -> dict:
    """The plan drives the robot's actuators in full physics, liquid and all."""
    plan = _load_plan(run_dir / "plan.npz")
    env = PouringEnv(particles=config.particles, obstacles=config.scene().obstacles)
    recorder = StateRecorder(every=max(1, round(1.0 / (config.video_fps * env.dt))))
    options = {"bottle_grasp": config.bottle_grasp, "glass_grasp": config.glass_grasp}
    result = replay_plan(plan, env, seed=config.seed, options=options, on_step=recorder)
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
    model, raw, arrays = _load_model(run_dir / "model.npz")
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
    for name, draw in tqdm(drawings.items(), desc="figures", unit="figure", disable=None):
        plots.save(draw(), run_dir / "figures" / f"{name}.png")
    n_frames = write_video(run_dir / "video.mp4", _video_frames(config, states), config.video_fps)
    return {"video": {"frames": n_frames, "seconds": n_frames / config.video_fps}}


# --- Running -----------------------------------------------------------------------------------


# The report sections each stage writes, in report order.
_SECTIONS = {
    "observe": ("demos", "perception"),
    "learn": ("learning",),
    "optimize": ("optimization",),
    "replay": ("replay",),
    "figures": ("video",),
}
_STAGE_FUNCTIONS: dict[str, Callable[[Path, RunConfig], dict]] = {
    "observe": observe, "learn": learn, "optimize": optimize, "replay": replay, "figures": figures,
}


def run_stage(stage: str, run_dir: Path, config: RunConfig) -> dict:
    """Run one stage in ``run_dir`` with ``config`` (stored as ``config.json`` first) and merge
    its numbers, its time and the artifacts present into ``report.json``; the sections of later
    stages are dropped (they no longer follow from it). Returns the report."""
    if stage not in _STAGE_FUNCTIONS:
        raise ImitateError(f"stage {stage!r} unknown; accepted: {STAGES}")
    run_dir = Path(run_dir)
    save_json(run_dir / "config.json", config.to_json())
    start = time.perf_counter()
    sections = _STAGE_FUNCTIONS[stage](run_dir, config)
    seconds = time.perf_counter() - start
    previous = _previous_report(run_dir)
    earlier = STAGES[: STAGES.index(stage)]
    kept = {name for s in earlier for name in _SECTIONS[s]}
    report = {"seed": config.seed}
    for name in [name for s in STAGES for name in _SECTIONS[s]]:
        if name in sections:
            report[name] = sections[name]
        elif name in kept and name in previous:
            report[name] = previous[name]
    timings = {s: t for s, t in previous.get("timings", {}).items() if s in earlier}
    report["timings"] = {**timings, stage: seconds}
    report["artifacts"] = _artifacts(run_dir)
    save_json(run_dir / "report.json", report)
    return report


def load_config(run_dir: Path) -> RunConfig:
    """The ``config.json`` of ``run_dir``."""
    return RunConfig.from_json(load_json(Path(run_dir) / "config.json"))


# --- Helpers -----------------------------------------------------------------------------------


def pour_phase(mean: np.ndarray) -> np.ndarray:
    """Steps ``(T,) bool`` where the bottle is tilted beyond 80 % of its largest tilt from the
    start, given the GMR mean ``(T, 7)``: the low-variance pouring phase."""
    tilt = np.abs(mean[:, 3] - mean[0, 3])
    return tilt >= 0.8 * tilt.max()


def _task_demo(position, axis, names, gaze) -> np.ndarray:
    """Task-space demonstration ``(m, 7)`` from tracked points (axis centres) and axes of the
    objects ``names`` ``(n_objects, m, 3)``: the centres move back to the frames (bottoms)."""
    frames = {
        name: (position[k] - axis[k] * _HEIGHTS[name] / 2, axis[k]) for k, name in enumerate(names)
    }
    return task_space(*frames[objects.BOTTLE], *frames[objects.GLASS], gaze)


def _bridged(times, position, axis) -> tuple[np.ndarray, np.ndarray]:
    """Tracks ``(n_objects, m, 3)`` with the samples perception left missing (gaps too long to
    fill) bridged linearly in time, held at the ends; axes renormalised."""
    position, axis = position.copy(), axis.copy()
    for k in range(len(position)):
        ok = np.all(np.isfinite(position[k]) & np.isfinite(axis[k]), axis=-1)
        if not ok.any():
            raise ImitateError(
                f"object {k} was tracked in none of the frames of the demonstration at "
                f"{times[0]:.2f}..{times[-1]:.2f} s; see figures/observation.png"
            )
        for values in (position[k], axis[k]):
            for c in range(3):
                values[:, c] = np.interp(times, times[ok], values[ok, c])
    return position, axis / np.linalg.norm(axis, axis=-1, keepdims=True)


def _smoothed(position, axis, frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Tracks ``(n_objects, m, 3)`` smoothed over time by a quadratic Savitzky-Golay filter of
    ``frames`` (odd; below 5: unchanged), axes renormalised."""
    if frames < 5 or frames > position.shape[1]:
        return position, axis
    position, axis = (savgol_filter(v, frames, 2, axis=1) for v in (position, axis))
    return position, axis / np.linalg.norm(axis, axis=-1, keepdims=True)


def _true_demos(observations: Observations) -> list[np.ndarray]:
    """The demonstrations cut from the ground truth at the true boundaries."""
    truth, tracks = observations.truth, observations.tracks
    demos = []
    for start, end in truth.boundaries:
        inside = (tracks.times >= start) & (tracks.times <= end)
        demos.append(
            _task_demo(
                truth.position[:, inside], truth.axis[:, inside], tracks.objects, tracks.gaze
            )
        )
    return demos


def _demo_counts(found: np.ndarray, true: np.ndarray) -> dict:
    """Detected and expected demonstrations; the largest boundary error [s] of the matched
    ones (each true demonstration to the detected one nearest in start time)."""
    nearest = np.abs(found[:, None, 0] - true[None, :, 0]).argmin(axis=0)
    return {
        "detected": len(found),
        "expected": len(true),
        "boundary_err_s_max": float(np.abs(found[nearest] - true).max()),
    }


def _tracking_errors(observations: Observations) -> dict:
    """Position [mm] and axis-angle [deg] errors of the tracks against the ground truth."""
    tracks, truth = observations.tracks, observations.truth
    pos = np.linalg.norm(tracks.position - truth.position, axis=-1) * 1e3
    turn = np.angle(np.exp(1j * (tracks.angle - truth.angle)))
    pos, turn = pos[np.isfinite(pos)], np.degrees(np.abs(turn[np.isfinite(turn)]))
    return {
        "pos_err_mm_median": float(np.median(pos)),
        "pos_err_mm_p95": float(np.percentile(pos, 95)),
        "angle_err_deg_median": float(np.median(turn)),
        "detected_fraction": float(tracks.detected.mean()),
        "long_gaps": len(tracks.long_gaps),
    }


def _model_arrays(model: LearnedModel, prefix: str) -> dict[str, np.ndarray]:
    g = model.gmm
    arrays = {
        "data": model.data, "weights": g.weights_, "means": g.means_,
        "covariances": g.covariances_, "bic_curve": model.bic_curve, "times": model.times,
        "mean": model.mean, "covariance": model.covariance,
    }
    return {prefix + name: value for name, value in arrays.items()}


def _load_model(path: Path) -> tuple[LearnedModel, LearnedModel, dict[str, np.ndarray]]:
    """The learned model (with DTW), the one without DTW (Fig. 4) and all arrays."""
    names = ("data", "weights", "means", "covariances", "bic_curve", "times", "mean", "covariance")
    required = names + tuple("raw_" + n for n in names) + ("bic_fast", "bic_full")
    arrays = load_npz(path, required=required)

    def model(prefix: str) -> LearnedModel:
        a = {name: arrays[prefix + name] for name in names}
        gmm = GMM.from_parameters(a.pop("weights"), a.pop("means"), a.pop("covariances"))
        return LearnedModel(gmm=gmm, alignment=None, **a)

    return model(""), model("raw_"), arrays


def _task_map(config: RunConfig, gaze: np.ndarray) -> TaskMap:
    """The robot's task map in the scene of ``config``, in the gaze frame of the observation."""
    base = planning_task(config.scene())
    return TaskMap(base.kin, objects.BOTTLE, objects.GLASS, gaze, PlanConfig().control.fixed_joints)


def _plan(task: TaskMap, model: dict[str, np.ndarray], config: RunConfig, weight: float) -> Plan:
    variance = np.diagonal(model["covariance"], axis1=1, axis2=2)
    means, covariances = model["means"], model["covariances"]
    return optimise(
        task, model["times"], model["mean"], variance, means[:, 0], humanoid.rest_pose(),
        PlanConfig(collision_weight=weight, max_iter=config.max_iter),
        np.sqrt(covariances[:, 0, 0]), model["weights"],
    )


def _plan_arrays(plan: Plan) -> dict[str, np.ndarray]:
    arrays = {}
    for f in dataclasses.fields(Plan):
        value = getattr(plan, f.name)
        if f.name == "costs":
            arrays.update({f"cost_{term}": v for term, v in value.items()})
        elif f.name == "closest":
            arrays[f.name] = np.array(value or (), dtype=str)
        else:
            arrays[f.name] = np.asarray(value)
    return arrays


def _load_plan(path: Path) -> Plan:
    names = [f.name for f in dataclasses.fields(Plan) if f.name != "costs"]
    a = load_npz(path, required=tuple(names))
    values = {name: a[name] if a[name].ndim else a[name].item() for name in names}
    values["closest"] = tuple(str(n) for n in a["closest"]) or None
    values["message"] = str(a["message"])
    values["costs"] = {k.removeprefix("cost_"): v for k, v in a.items() if k.startswith("cost_")}
    return Plan(**values)


def _deviation(plan: Plan, zero: Plan, weight: float) -> dict:
    """Squared deviation of the positions from the GMR mean, and the share of it in the steps
    whose GMR position variance is above its median (paper Fig. 9)."""
    dev = np.sum((plan.x[:, :3] - plan.mean[:, :3]) ** 2, axis=1)
    extra = np.sum((plan.x[:, :3] - zero.x[:, :3]) ** 2, axis=1)
    var = plan.variance[:, :3].sum(axis=1)
    high = var > np.median(var)
    return {
        "weight": weight,
        "min_distance_m": plan.min_distance,
        "deviation_m2": float(dev.sum()),
        "deviation_high_variance_share": float(dev[high].sum() / max(dev.sum(), 1e-12)),
        "change_from_first_m2": float(extra.sum()),
        "change_high_variance_share": float(extra[high].sum() / max(extra.sum(), 1e-12)),
    }


def _snapshots(config: RunConfig, states: dict[str, np.ndarray], n: int = 6):
    """``n`` close-up images over the replay and their times [s]."""
    index = np.linspace(0, len(states["qpos"]) - 1, n + 2).round().astype(int)[1:-1]
    chosen = {name: states[name][index] for name in ("qpos", "mocap_pos", "mocap_quat")}
    images = list(replay_frames(config.scene(), chosen, 400, 300, close_up(), shadows=True))
    return images, index * float(states["state_dt"])


def _video_frames(config: RunConfig, states: dict[str, np.ndarray]):
    size = (config.video_width, config.video_height)
    motion = script_demonstrations(TeacherConfig(n_demos=config.n_demos, seed=config.seed))
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


def _previous_report(run_dir: Path) -> dict:
    path = run_dir / "report.json"
    return load_json(path) if path.exists() else {}


def _artifacts(run_dir: Path) -> dict[str, str]:
    """Relative paths of the artifacts present, by name."""
    names = (
        "config.json", "observations.npz", "demos.npz", "model.npz", "plan.npz", "replay.npz",
        "report.json", "video.mp4", *(f"figures/{name}.png" for name in _FIGURES),
    )
    return {
        Path(name).stem: name for name in names
        if (run_dir / name).exists() or name == "report.json"
    }
