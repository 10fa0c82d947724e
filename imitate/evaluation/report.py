"""What an evaluation reports: the summary (success rate with its Wilson interval, outcome
counts, the task's score, clearances, timings), the outcome figure and the videos of failures.
The task (:class:`~imitate.envs.task.Task`) names the outcomes and the score
(``Task.score``)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Patch, Rectangle

from imitate.envs.task import Task
from imitate.envs.video import StateRecorder, captioned, replay_frames, write_video
from imitate.evaluation.record import TrialRecord, is_number, score_keys, task_value
from imitate.evaluation.trial import physics, plan_variation
from imitate.evaluation.variation import Variation
from imitate.learning import LearnedModel
from imitate.models.scene import TABLE_X
from imitate.motion import PlanConfig
from imitate.motion.replay import measure
from imitate.rundir.artifacts import write_atomic

__all__ = [
    "colours", "failure_video", "plot_outcomes", "summarize", "summarize_teachers",
    "teacher_table", "text", "wilson",
]

# The colours of the outcomes every task has, and of a task's own, in its order.
COLOURS = {
    "success": "tab:green", "plan_collision": "tab:red", "physics_contact": "tab:orange",
    "diverged": "black",
}
OWN_COLOURS = ("tab:purple", "tab:blue", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")
PLACES = ("none", "random", "in_path")  # where a variation's obstacle was placed
MARGIN = PlanConfig().margin  # [m], the clearance every variation's plan aims for


def wilson(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """Wilson score interval ``(low, high)`` of a success rate (95 % for ``z = 1.96``); exactly
    0 below none and 1 above all (where rounding would leave ``1 - 1e-16``)."""
    if n == 0:
        return 0.0, 1.0
    p, z2 = successes / n, z * z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = z * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    low = 0.0 if successes == 0 else max(0.0, centre - half)
    high = 1.0 if successes == n else min(1.0, centre + half)
    return low, high


def colours(task: Task) -> dict[str, str]:
    """The colour of each of ``task``'s outcomes."""
    own = iter(OWN_COLOURS)
    return {o: COLOURS.get(o) or next(own) for o in task.outcomes}


def place(record: TrialRecord) -> str:
    """Where the record's obstacle is: one of :data:`PLACES`."""
    settings = record["settings"]
    if settings["obstacle"] is None:
        return "none"
    return "in_path" if settings["in_path"] else "random"


def summarize(records: Sequence[TrialRecord], task: Task) -> dict:
    """``summary.json``'s numbers over ``records`` (``results.jsonl`` lines of ``task``): the
    score's keys are named after it (``Task.score``: ``<name>_mean``, ``<name>_min``,
    ``<name>_threshold``, ``low_<name>``)."""
    n = len(records)
    name, threshold = task.score.name, task.score.threshold
    mean_key, min_key = score_keys(task)
    outcomes = [r["outcome"] for r in records]
    successes = outcomes.count("success")
    low, high = wilson(successes, n)
    seconds = np.array([r["seconds"] for r in records])
    clear = [r for r in records if r["plan"]["min_distance_m"] >= 0]
    # plan minus physics [mm], over the plans that keep clear
    gap: dict[str, float] = {"plans": len(clear)}
    if clear:
        values = np.array([r["clearance_gap_m"] for r in clear]) * 1000
        gap.update(median=float(np.median(values)), p95=float(np.percentile(values, 95)),
                   max=float(values.max()))
    by_place = {
        p: {o: sum(place(r) == p and r["outcome"] == o for r in records) for o in task.outcomes}
        for p in PLACES
    }
    kept = [r for r in records if r["plan"]["min_distance_m"] >= MARGIN]
    margin = {  # what physics does with the plans that keep the planner's margin
        "margin_m": MARGIN, f"{name}_threshold": threshold, "plans": len(kept),
        "physics_contact": sum(r["physics_min_distance_m"] < 0 for r in kept),
        f"low_{name}": sum(task_value(r, min_key) < threshold for r in kept),
    }
    pushed = [r for r in records if r["plan"].get("nullspace_push", False)]
    return {
        "variations": n,
        "success_rate": successes / n,
        "success_wilson95": [low, high],
        "outcomes": {o: outcomes.count(o) for o in task.outcomes},
        "outcomes_by_obstacle": by_place,
        mean_key: float(np.mean([task_value(r, mean_key) for r in records])),
        min_key: float(np.min([task_value(r, min_key) for r in records])),
        "clearance_gap_mm": gap,
        "kept_margin": margin,
        "nullspace_push": {  # plans the attractors alone could not keep clear
            "plans": len(pushed), "success": sum(r["outcome"] == "success" for r in pushed),
        },
        "seconds_per_variation": {
            "mean": float(seconds.mean()), "median": float(np.median(seconds)),
            "max": float(seconds.max()),
        },
    }


def summarize_teachers(
    records: Sequence[TrialRecord], digests: dict[int, str],
    default_runs: dict[int, dict | None],
    task: Task,
) -> list[dict]:
    """Per teacher (seed: digest of its records): its success with the Wilson interval, the
    task's score over its variations (the smallest, the mean of each variation's smallest and
    the mean of their means: ``<name>_min``, ``<name>_min_mean``, ``<name>_mean``), its failures
    (id, outcome, where the obstacle was) and its default run (``default_runs``: the ``replay``
    section of its report, or ``None``)."""
    mean_key, min_key = score_keys(task)
    rows = []
    for teacher, digest in digests.items():
        own = [r for r in records if r["digest"] == digest]
        successes = sum(r["outcome"] == "success" for r in own)
        lows = [task_value(r, min_key) for r in own]
        rows.append({
            "seed": teacher, "digest": digest, "variations": len(own), "success": successes,
            "success_rate": successes / max(len(own), 1),
            "success_wilson95": list(wilson(successes, len(own))),
            min_key: float(min(lows)) if own else None,
            f"{min_key}_mean": float(np.mean(lows)) if own else None,
            mean_key: float(np.mean([task_value(r, mean_key) for r in own])) if own else None,
            "failures": [
                {"id": r["id"], "outcome": r["outcome"], "obstacle": place(r)}
                for r in own if r["outcome"] != "success"
            ],
            "default_run": default_runs.get(teacher),
        })
    return rows


def teacher_table(rows: Sequence[dict], task: Task) -> str:
    """The teachers of :func:`summarize_teachers` as a markdown table."""
    name, measure = task.score.name, task.score.measure
    min_key = score_keys(task)[1]
    lines = [
        f"| teacher seed | default run: {measure} per replay | success | Wilson 95 % "
        f"| smallest {name} | mean of the smallest | failures (id: outcome) |",
        "|---|---|---|---|---|---|---|",
    ]
    for t in rows:
        low, high = t["success_wilson95"]
        failures = ", ".join(f"{f['id']}: {f['outcome']}" for f in t["failures"]) or "none"
        lines.append(
            f"| {t['seed']} | {_default_run(t['default_run'], measure)} "
            f"| {t['success']}/{t['variations']} | {low:.3f}..{high:.3f} "
            f"| {t[min_key]:.3f} | {t[f'{min_key}_mean']:.3f} | {failures} |"
        )
    return "\n".join(lines)


def _default_run(run: object, measure: str) -> str:
    """A teacher's default run (its report's ``replay`` section, read as it is) as the table
    shows it: each replay's ``measure`` and the success; "-" where it has no such values."""
    if not isinstance(run, dict):
        return "-"
    values = run.get(f"{measure}s")
    if not (isinstance(values, list) and all(is_number(v) for v in values)
            and isinstance(run.get("success"), bool)):
        return "-"
    return f"{' '.join(f'{p:.3f}' for p in values)} ({'success' if run['success'] else 'failure'})"


def text(summary: dict, out: Path, task: Task) -> str:
    """The summary of an evaluation of ``task`` in a few lines (what ``imitate eval`` prints);
    ``out``: the eval folder."""
    n, run = summary["variations"], summary["run"]
    name, measure = task.score.name, task.score.measure
    mean_key, min_key = score_keys(task)
    low, high = summary["success_wilson95"]
    successes = summary["outcomes"]["success"]
    workers = run["workers"]
    where = f"{workers} worker{'s' * (workers != 1)}" if run["backend"] == "local" else "Ray"
    by_place = ", ".join(
        f"{p} {c['success']}/{sum(c.values())}" for p, c in summary["outcomes_by_obstacle"].items()
    )
    gap, seconds = summary["clearance_gap_mm"], summary["seconds_per_variation"]
    kept, push = summary["kept_margin"], summary["nullspace_push"]
    teachers = summary.get("teachers", [])
    per_teacher = [teacher_table(teachers, task)] if len(teachers) > 1 else []
    return "\n".join([
        f"eval: {n} variations of {len(teachers) or 1} teacher{'s' * (len(teachers) > 1)} "
        f"({run['ran']} run now on {where} in {run['wall_seconds']:.1f} s, "
        f"1-min load average {run['load_average_start'][0]:.1f} at the start, "
        f"{run['load_average_end'][0]:.1f} at the end), suite digest {summary['suite_digest']}",
        f"success: {successes}/{n} = {summary['success_rate']:.3f} (95 % Wilson interval "
        f"{low:.3f}..{high:.3f})",
        *per_teacher,
        "outcomes: " + ", ".join(f"{o} {c}" for o, c in summary["outcomes"].items()),
        f"successes by obstacle: {by_place}",
        f"{name} over the replays: mean {summary[mean_key]:.3f}, min {summary[min_key]:.3f}",
        f"plan - physics clearance over the {gap['plans']} plans that keep clear [mm]: "
        + ", ".join(f"{k} {v:.2f}" for k, v in gap.items() if k != "plans"),
        f"plans that keep the {kept['margin_m'] * 1000:g} mm margin: {kept['plans']}; of them "
        f"touching in physics {kept['physics_contact']}, {measure} below "
        f"{kept[f'{name}_threshold']:g} in a replay {kept[f'low_{name}']}",
        f"plans with the null-space push: {push['plans']}; of them successes {push['success']}",
        f"seconds per variation: mean {seconds['mean']:.1f}, median {seconds['median']:.1f}, "
        f"max {seconds['max']:.1f}",
        f"results: {out / 'results.jsonl'}, {out / 'summary.json'}, {out / 'outcomes.png'}",
        f"page: {out / 'report.html'}",
    ])


def plot_outcomes(records: Sequence[TrialRecord], path: np.ndarray, task: Task) -> Figure:
    """Top view of the front of the table: each obstacle's footprint (filled: placed in the
    path), edged by its outcome (of ``task``'s), over the weight-0 path points ``path`` (P, 3);
    beside it the outcome counts by where the obstacle is."""
    colour_of = colours(task)
    figure = Figure(figsize=(11, 5), layout="constrained")
    top, bars = figure.subplots(1, 2, width_ratios=(3, 2))
    for r in records:
        obstacle = r["settings"]["obstacle"]
        if obstacle is None:
            continue
        (x, y, _), size = obstacle["pos"], obstacle["size"]
        colour = colour_of[r["outcome"]]
        style: dict[str, Any] = dict(
            edgecolor=colour, facecolor=colour if r["settings"]["in_path"] else "none",
            alpha=0.8, lw=1.2,
        )
        if obstacle["shape"] == "box":
            top.add_patch(Rectangle((x - size[0], y - size[1]), 2 * size[0], 2 * size[1], **style))
        else:
            top.add_patch(Circle((x, y), size[0], **style))
    if len(path):
        top.plot(path[:, 0], path[:, 1], ".", ms=3, color="0.3", label="held objects at weight 0")
    top.axvline(TABLE_X[0], color="0.4", lw=1, ls="--", label="table edge")
    handles = [Patch(color=colour_of[o], label=o) for o in task.outcomes]
    top.legend(handles=[*top.get_legend_handles_labels()[0], *handles], fontsize=8,
               loc="upper left", bbox_to_anchor=(1.02, 1.0))
    top.set(xlim=(TABLE_X[0] - 0.1, 0.85), ylim=(-0.45, 0.45), aspect="equal", xlabel="x [m]",
            ylabel="y [m]", title="obstacles by outcome (filled: placed in the path)")
    bottom = np.zeros(len(PLACES))
    for outcome in task.outcomes:
        counts = np.array(
            [sum(place(r) == p and r["outcome"] == outcome for r in records) for p in PLACES]
        )
        bars.bar(PLACES, counts, bottom=bottom, color=colour_of[outcome], label=outcome)
        bottom += counts
    bars.set(ylabel="variations", title="outcomes by obstacle")
    return figure


def failure_video(
    path: Path, learned: LearnedModel, gaze: np.ndarray, record: dict, task: Task,
    fps: float = 25.0,
) -> int:
    """Video of a failed variation's worst replay (the one with the smallest score, or the
    first that touched), replayed again from its settings; returns the number of frames."""
    variation = Variation.from_json(record["settings"])
    replays = record["replays"]
    touched = [r for r in replays if r["min_distance_m"] < 0]
    worst = touched[0] if touched else min(replays, key=lambda r: r[task.score.measure])
    plan = plan_variation(learned, gaze, variation, task)
    env = physics(variation, task)
    recorder = StateRecorder(every=max(1, round(1.0 / (fps * env.dt))))
    measure(task, plan, env, seed=worst["seed"], gaze=gaze, options=variation.options,
            on_step=recorder)
    caption = f"variation {variation.id}: {record['outcome'].replace('_', ' ')}"
    states = recorder.arrays()
    frames = captioned(replay_frames(variation.scene(task), states, 640, 480), caption)
    counted: list[int] = []
    write_atomic(path, lambda tmp: counted.append(write_video(tmp, frames, fps)))
    return counted[0]
