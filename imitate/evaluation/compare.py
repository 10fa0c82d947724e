"""``imitate compare``: similarity weightings on the same variations, paired, with inference over
teachers.

Every weighting plans and replays the same variations of a suite (the same settings but
``similarity``) with the learned models of the same teachers. The unit of inference is the
teacher, the learned model (:mod:`~imitate.evaluation.inference`): per teacher and pair of
weightings, the paired difference of the success rate, of the mean of the task's score (each
variation's worst replay: ``Task.score``) and of the mean Mahalanobis deviation from the
demonstrations (``mahalanobis.rms``), and over teachers their mean with a t interval and an
exact permutation test. The exact McNemar test on success pools the variations and so speaks
of these learned models only; how far the constraints moved the task's critical phase from each
weighting's unconstrained reproduction (``change``) is descriptive. The keys and words named
after the score and the critical phase are the run's task's (``<score>``, ``<phase>``).

Whether a verdict replicates (:mod:`~imitate.evaluation.replication`): the development
teachers (the run's seed and the next ones) and, with ``confirm``, a confirmation block of
teachers from seed 1000 up, on the same variations; a primary endpoint declared before the runs,
reported per block.

With a sweep (a numeric suite key and its values), every level is compared: per weighting the
success and the score against the level with their bands over teachers, the level at 50 %
success (ED50) with a bootstrap interval over teachers, and per teacher the first level whose
plans (their median) keep the planner's margin.

Writes under ``RUN_DIR/compare/<suite name>/`` (``<suite name>-<key>/`` for a sweep):
``results.jsonl`` (resumable as ``imitate eval``'s), ``compare.json``, ``compare.md`` (the
tables) and ``compare.png`` (:mod:`~imitate.evaluation.compare_report`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
import logging
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from scipy import stats

from imitate.envs import tasks
from imitate.envs.task import Task
from imitate.errors import ImitateError, quoted
from imitate.evaluation.compare_report import markdown, measures, plot_comparison, plot_dose
from imitate.evaluation.inference import ed50, mean_ci, teacher_effect
from imitate.evaluation.record import TrialRecord, change_keys, error_keys, score_keys, task_value
from imitate.evaluation.replication import CONFIRMATION_SEED, parse_primary, replication
from imitate.evaluation.report import MARGIN, wilson
from imitate.evaluation.sensitivity import with_importance
from imitate.evaluation.suite import Suite, keys
from imitate.evaluation.suite_run import (
    RESULTS,
    Draw,
    check_counts,
    check_task,
    draw_jobs,
    run_jobs,
)
from imitate.evaluation.teachers import MAX_TEACHERS, check_model, check_run, teachers
from imitate.figures import plots
from imitate.motion import SIMILARITIES
from imitate.rundir.artifacts import (
    refuse_hard_link,
    refuse_link,
    save_bytes,
    save_json,
    write_atomic,
)
from imitate.rundir.lock import locked
from imitate.stages import provenance

__all__ = ["compare", "dose", "out_folder", "paired", "parse_sweep", "settings_digest"]

log = logging.getLogger(__name__)

TEACHERS = 10  # teachers a comparison uses unless told: the unit of its inference


MAX_LEVELS = 20  # values of a --sweep: each level is a comparison of its own


def parse_sweep(text: str, task: str = tasks.DEFAULT) -> tuple[str, tuple[float, ...]]:
    """``KEY=V1,V2,...`` as the key (of a suite of ``task``) and its increasing values.

    Raises:
        ImitateError: not of that form, a key that is not a numeric suite key, or values that
            are not increasing numbers the key accepts.
    """
    key, _, values = text.partition("=")
    accepted = keys(task)
    numeric = [k for k, v in accepted.items() if not (v.is_name or v.is_switch or v.integer)
               and v.choices is None]
    refused = f"sweep={quoted(text)} not accepted: KEY=V1,V2,... with KEY one of {numeric} and " \
              "two or more increasing values, e.g. path_length_weight=10,20,40,70"
    if key not in numeric:
        raise ImitateError(refused)
    try:
        levels = tuple(float(v) for v in values.split(","))
    except ValueError:
        raise ImitateError(refused) from None
    if len(levels) < 2 or any(b <= a for a, b in itertools.pairwise(levels)):
        raise ImitateError(refused)
    if len(levels) > MAX_LEVELS:
        raise ImitateError(
            f"sweep of {len(levels)} values not accepted: at most {MAX_LEVELS} (each is a whole "
            "comparison); give fewer"
        )
    k = accepted[key]
    outside = [v for v in levels if not k.low <= v <= k.high]
    if outside:
        raise ImitateError(
            f"sweep={quoted(text)} not accepted: {key} {outside[0]:g} is outside {k.low:g}.."
            f"{k.high:g}; give values within it"
        )
    return key, levels


def out_folder(run_dir: Path, name: str, sweep: str | None = None) -> Path:
    """Where a comparison of the suite ``name`` writes: ``RUN_DIR/compare/<name>/``, or
    ``<name>-<key>/`` for a sweep (``sweep``: ``KEY=...`` or the key)."""
    folder = f"{name}-{sweep.partition('=')[0]}" if sweep else name
    return Path(run_dir) / "compare" / folder


def compare(
    run_dir: Path,
    suite: Suite,
    similarities: Sequence[str],
    *,
    name: str = "default",
    n: int | None = None,
    seed: int = 0,
    n_teachers: int = TEACHERS,
    sweep: tuple[str, Sequence[float]] | None = None,
    workers: int | None = None,
    ray: str | None = None,
    progress: bool | None = None,
    confirm: int = 0,
    primary: str | None = None,
) -> dict:
    """Plan and replay ``n`` variations of ``suite`` (drawn with ``seed``) with each of
    ``similarities``, for ``n_teachers`` teachers of ``run_dir`` (the run's own first; their
    models are shared with ``imitate eval``'s, under ``eval/teachers/``), at every level of
    ``sweep`` (a key and its values, :func:`parse_sweep`) if given; ``name`` names the output
    folder. ``confirm`` more teachers (seeds from
    :data:`~imitate.evaluation.replication.CONFIRMATION_SEED`) form the confirmation block;
    ``primary`` (``"A-B"``, default the first two weightings) is the endpoint reported per block
    (:func:`~imitate.evaluation.replication.replication`). Returns ``compare.json``'s contents.

    Raises:
        ImitateError: an unknown or repeated weighting, fewer than two, a ``primary`` not of
            two of them, ``confirm`` outside 0..100 or with a sweep, or what
            :func:`~imitate.evaluation.suite_run.evaluate` refuses (a suite of another task
            than the run's among it).
    """
    similarities = tuple(similarities)
    unknown = [s for s in similarities if s not in SIMILARITIES]
    if unknown or len(set(similarities)) != len(similarities) or len(similarities) < 2:
        raise ImitateError(
            f"similarities={quoted(','.join(similarities))} not accepted: two or more of "
            f"{', '.join(SIMILARITIES)}, each once"
        )
    endpoint = parse_primary(primary or "-".join(similarities[:2]), similarities)
    if isinstance(confirm, bool) or not isinstance(confirm, int) or not (
        0 <= confirm <= MAX_TEACHERS
    ):
        raise ImitateError(
            f"--confirm {confirm!r} not accepted: a whole number of teachers in 0..{MAX_TEACHERS}"
        )
    if confirm and sweep is not None:
        raise ImitateError(
            "--confirm with --sweep not accepted: the blocks are compared at one level; give "
            "the level as --collision-weight or in a suite file"
        )
    confirmation = tuple(range(CONFIRMATION_SEED, CONFIRMATION_SEED + confirm))
    levels = [suite] if sweep is None else [suite.replace(**{sweep[0]: v}) for v in sweep[1]]
    start = time.perf_counter()
    run_dir = check_run(run_dir)
    task = check_task(run_dir, suite)
    with locked(run_dir, f"imitate compare {run_dir}"):
        n, workers = check_counts(suite, n, workers)
        check_model(run_dir)
        out = out_folder(run_dir, name, sweep and sweep[0])
        for inside in (out, out / RESULTS):
            refuse_link(inside)
        refuse_hard_link(out / RESULTS)
        out.mkdir(parents=True, exist_ok=True)
        log.info("compare: primary endpoint %s - %s (success per teacher)%s", *endpoint,
                 f", confirmation teachers {confirmation[0]}-{confirmation[-1]}"
                 if confirmation else "")
        models = teachers(run_dir, run_dir / "eval", n_teachers, confirmation, workers)
        if "importance" in similarities:
            models = with_importance(run_dir, models)
        code, model_bytes = provenance.code_digest(), {t.seed: t.digest_bytes for t in models}
        drawn: dict[tuple[int, str], list[Draw]] = {}
        places: dict = {}  # each teacher's weight-0 path and critical place, at every level
        for i, level in enumerate(levels):
            base = draw_jobs(models, level, seed, n, places)
            for s in similarities:
                drawn[i, s] = [
                    Draw(
                        d.teacher,
                        level.replace(similarity=s).digest(
                            seed, d.teacher, model_bytes[d.teacher], code),
                        d.path, tuple(dataclasses.replace(v, plan=v.plan.replace(similarity=s))
                                      for v in d.variations),
                    )
                    for d in base
                ]
        everything = [d for draws in drawn.values() for d in draws]
        log.info("compare: %d weightings x %d teachers x %d variations%s", len(similarities),
                 len(models), n, "" if sweep is None else f" x {len(levels)} levels")
        records, run = run_jobs(out / RESULTS, everything, models, workers, ray, progress, task)
        compared = [
            paired({
                s: [records[(d.digest, v.id)] for d in drawn[i, s] for v in d.variations]
                for s in similarities
            }, task)
            for i in range(len(levels))
        ]
        result = {
            "suite_name": name, "task": task.name, "suite": suite.to_json(), "seed": seed,
            "teachers": [t.seed for t in models], "variations_per_teacher": n,
        }
        if sweep is None:
            result.update(compared[0])
            ordered = {s: [records[(d.digest, v.id)] for d in drawn[0, s] for v in d.variations]
                       for s in endpoint}
            result["replication"] = replication(
                {s: np.array([r["outcome"] == "success" for r in rs]) for s, rs in ordered.items()},
                np.array([r["teacher"] for r in ordered[endpoint[0]]]), endpoint, confirmation,
            )
            figure = plot_comparison(result, task)
        else:
            result.update(sweep={"key": sweep[0], "values": list(sweep[1])}, levels=compared,
                          dose=dose(sweep[1], compared, task))
            figure = plot_dose(result, task)
        result["run"] = {**run, "command_seconds": time.perf_counter() - start}
        save_json(out / "compare.json", result)
        text = markdown(result, task) + "\n"
        write_atomic(out / "compare.md", lambda tmp: tmp.write_text(text))
        save_bytes(out / "compare.png", plots.figure_png(figure))
        return result


def settings_digest(record: TrialRecord) -> str:
    """A record's settings but its weighting (equal for the same variation in every
    weighting)."""
    settings = {k: v for k, v in record["settings"].items() if k != "similarity"}
    text = json.dumps({"teacher": record["teacher"], **settings}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def paired(by_weighting: dict[str, list[TrialRecord]], task: Task) -> dict:
    """Per weighting (its records of ``task``, in the same order for every weighting): success
    over teachers (mean, t interval) and over all variations (Wilson interval), and per teacher
    its success rate, mean score, median Mahalanobis deviation and median clearance, and how
    many plans the null-space push changed and had fixtures; per pair: the teacher-level effect
    of each of :func:`measures` (:func:`~imitate.evaluation.inference.teacher_effect`), the
    McNemar test within these models, and the descriptive change of the critical phase.

    Raises:
        ImitateError: the weightings' records are not of the same variations.
    """
    keys = {s: [settings_digest(r) for r in rs] for s, rs in by_weighting.items()}
    first, *others = keys
    for s in others:
        if len(keys[s]) != len(keys[first]):
            raise ImitateError(
                f"the weightings' records are not of the same variations: {len(keys[s])} of "
                f"{s}, {len(keys[first])} of {first}; remove the comparison's results.jsonl "
                "and run it again"
            )
        for r, a, b in zip(by_weighting[s], keys[first], keys[s], strict=True):
            if a != b:
                raise ImitateError(
                    f"the weightings' records are not of the same variations: {s}'s record of "
                    f"teacher {r['teacher']}, variation {r['id']} has other settings than "
                    f"{first}'s; remove the comparison's results.jsonl and run it again"
                )
    phase, min_key = task.phase, score_keys(task)[1]
    moved_m, moved_deg = change_keys(task)
    weightings: dict[str, dict[str, Any]] = {}
    for s, rs in by_weighting.items():
        ok = [r["outcome"] == "success" for r in rs]
        change = {k: np.array([r["change"][k] for r in rs])
                  for k in (moved_m, moved_deg, "low_variance_m")}
        by_teacher = _by_teacher(rs, task)
        mean, ci = mean_ci(np.array([t["success_rate"] for t in by_teacher.values()]))
        weightings[s] = {
            "variations": len(rs), "success": sum(ok), "success_rate": sum(ok) / len(rs),
            "success_over_teachers": {"mean": mean, "ci95": ci},
            "success_wilson95": list(wilson(sum(ok), len(rs))),
            "by_teacher": by_teacher,
            "fixtures": {f: sum(r["settings"].get(f) is not None for r in rs)
                         for f in ("shelf", "plate")},
            "pushed": sum(r["plan"]["nullspace_push"] for r in rs),
            "outcomes": {o: sum(r["outcome"] == o for r in rs) for o in
                         sorted({r["outcome"] for r in rs})},
            f"{min_key}_mean": float(np.mean([task_value(r, min_key) for r in rs])),
            "mahalanobis_rms_median": float(np.median([r["mahalanobis"]["rms"] for r in rs])),
            "clearance_median_mm": float(np.median([r["plan"]["min_distance_m"] for r in rs]))
            * 1000,
            f"{phase}_error_median_mm": 1000 * float(
                np.median([task_value(r["plan"], error_keys(task)[0]) for r in rs])
            ),
            f"{phase}_change_mm": _spread(change[moved_m] * 1000),
            f"{phase}_change_deg": _spread(change[moved_deg]),
            "low_variance_change_mm": _spread(change["low_variance_m"] * 1000),
        }
    pairs = []
    for a, b in itertools.combinations(by_weighting, 2):
        ra, rb = by_weighting[a], by_weighting[b]
        ta, tb = weightings[a]["by_teacher"], weightings[b]["by_teacher"]
        sa = np.array([r["outcome"] == "success" for r in ra])
        sb = np.array([r["outcome"] == "success" for r in rb])
        only_a, only_b = int(np.sum(sa & ~sb)), int(np.sum(~sa & sb))
        mcnemar = (
            stats.binomtest(only_a, only_a + only_b, 0.5).pvalue if only_a + only_b else 1.0
        )
        moved = (np.array([r["change"][moved_m] for r in ra])
                 - np.array([r["change"][moved_m] for r in rb])) * 1000
        pairs.append({
            "a": a, "b": b,
            "teacher_level": {
                m: teacher_effect(np.array([ta[t][m] - tb[t][m] for t in ta]))
                for m in measures(task)
            },
            "within_models": {
                "both": int(np.sum(sa & sb)), "only_a": only_a, "only_b": only_b,
                "neither": int(np.sum(~sa & ~sb)), "mcnemar_p": float(mcnemar),
            },
            f"{phase}_change_median_difference_mm": float(np.median(moved)),
        })
    return {"weightings": weightings, "pairs": pairs}


def dose(values: Sequence[float], levels: Sequence[dict], task: Task) -> dict:
    """The dose response of a sweep of ``task``: per weighting, at every level (``values``,
    their :func:`paired` results ``levels``) the mean over teachers of the success rate and of
    the mean score (``<score>``) with their t intervals, the median Mahalanobis deviation, the
    critical phase's error (the plan's largest relative position error from the GMR mean there)
    and clearance; its ED50
    (:func:`~imitate.evaluation.inference.ed50`; success rising or falling with the level as
    all weightings' mean curves do together; beyond the levels as ``">300"`` or ``"<10"``);
    per teacher the first level whose plans keep the margin (``">L"``: none). Per pair: how
    many teachers' ED50 or first clearing level is surely at least twice as high with ``b`` as
    with ``a``, or with ``a`` as with ``b`` (a level beyond the sweep counts as a bound), and
    how many cannot be told."""
    x = np.asarray(values, float)
    error = f"{task.phase}_error_median_mm"
    weightings = list(levels[0]["weightings"])
    teachers_ = list(levels[0]["weightings"][weightings[0]]["by_teacher"])

    def per_teacher(s: str, what: str) -> np.ndarray:  # (teachers, levels)
        return np.array([[level["weightings"][s]["by_teacher"][t][what] for level in levels]
                         for t in teachers_])

    rates = {s: per_teacher(s, "success_rate") for s in weightings}
    slope = sum(r.mean(axis=0)[-1] - r.mean(axis=0)[0] for r in rates.values())
    rising = None if slope == 0 else bool(slope > 0)
    curves: dict[str, dict] = {}
    for s in weightings:
        scores = per_teacher(s, score_keys(task)[1])
        clear = per_teacher(s, "clearance_median_mm")
        found = ed50(x, rates[s], rising)
        kept = clear >= MARGIN * 1000
        totals = {k: [level["weightings"][s][k] for level in levels] for k in
                  ("mahalanobis_rms_median", error, "clearance_median_mm")}
        curves[s] = {
            "success": [_band(rates[s][:, j]) for j in range(len(x))],
            task.score.name: [_band(scores[:, j]) for j in range(len(x))],
            **totals,
            "ed50": _level(found["ed50"], x),
            "ed50_ci95": found["ci95"] and [_level(v, x) for v in found["ci95"]],
            "ed50_by_teacher": dict(zip(teachers_, (_level(v, x) for v in found["by_teacher"]),
                                        strict=True)),
            "first_clear_by_teacher": {
                t: float(x[np.argmax(k)]) if k.any() else f">{x[-1]:g}"
                for t, k in zip(teachers_, kept, strict=True)
            },
        }
    pairs = []
    for a, b in itertools.combinations(weightings, 2):
        row: dict = {"a": a, "b": b}
        for what in ("ed50", "first_clear"):
            ca, cb = curves[a][f"{what}_by_teacher"], curves[b][f"{what}_by_teacher"]
            bounds = [(_bounds(ca[t]), _bounds(cb[t])) for t in teachers_]
            row[what] = {
                "b_twice_a": sum(lb >= 2 * ha for (_, ha), (lb, _) in bounds),
                "a_twice_b": sum(la >= 2 * hb for (la, _), (_, hb) in bounds),
                "untold": sum(math.isnan(la + lb) for (la, _), (lb, _) in bounds),
            }
        pairs.append(row)
    return {"rising": rising, "weightings": curves, "pairs": pairs}


def _by_teacher(records: Sequence[TrialRecord], task: Task) -> dict[str, dict]:
    """Per teacher (its seed as text): variations, successes, the success rate, the mean of the
    smallest scores (``<score>_min``), the median Mahalanobis deviation and the median plan
    clearance [mm]."""
    min_key = score_keys(task)[1]
    groups: dict[str, list[TrialRecord]] = {}
    for r in records:
        groups.setdefault(str(r["teacher"]), []).append(r)
    return {
        t: {
            "variations": len(rs), "success": sum(r["outcome"] == "success" for r in rs),
            "success_rate": sum(r["outcome"] == "success" for r in rs) / len(rs),
            min_key: float(np.mean([task_value(r, min_key) for r in rs])),
            "mahalanobis_rms": float(np.median([r["mahalanobis"]["rms"] for r in rs])),
            "clearance_median_mm": float(np.median([r["plan"]["min_distance_m"] for r in rs]))
            * 1000,
        }
        for t, rs in groups.items()
    }


def _band(values: np.ndarray) -> dict:
    mean, ci = mean_ci(values)
    return {"mean": mean, "ci95": ci}


def _level(value: float, levels: np.ndarray) -> float | str | None:
    """A level, or where it lies beyond the swept ones (``">300"``, ``"<10"``); ``None`` for
    none (``nan``: curves that do not move)."""
    if math.isnan(value):
        return None
    if value == math.inf:
        return f">{levels[-1]:g}"
    if value == -math.inf:
        return f"<{levels[0]:g}"
    return float(value)


def _bounds(value: float | str | None) -> tuple[float, float]:
    """A level as the interval it is known to lie in: ``">300"`` is ``(300, inf)``, ``"<10"``
    ``(0, 10)``; no level (``None``) ``(nan, nan)``."""
    if value is None:
        return math.nan, math.nan
    if isinstance(value, str):
        bound = float(value[1:])
        return (bound, math.inf) if value[0] == ">" else (0.0, bound)
    return value, value


def _spread(values: np.ndarray) -> dict[str, float]:
    return {"median": float(np.median(values)), "p95": float(np.percentile(values, 95)),
            "max": float(values.max())}

