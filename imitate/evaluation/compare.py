"""``imitate compare``: similarity weightings on the same variations, paired, with inference over
teachers.

Every weighting plans and replays the same variations of a suite (the same settings but
``similarity``) with the learned models of the same teachers. The unit of inference is the
teacher, the learned model (:mod:`~imitate.evaluation.inference`): per teacher and pair of
weightings, the paired difference of the success rate, of the mean pour (each variation's worst
replay) and of the mean Mahalanobis deviation from the demonstrations (``mahalanobis.rms``),
and over teachers their mean with a t interval and an exact permutation test. The exact
McNemar test on success pools the variations and so speaks of these learned models only; how
far the constraints moved the pour from each weighting's unconstrained reproduction
(``change``) is descriptive.

With a sweep (a numeric suite key and its values), every level is compared: per weighting the
success and the pour against the level with their bands over teachers, the level at 50 %
success (ED50) with a bootstrap interval over teachers, and per teacher the first level whose
plans (their median) keep the planner's margin.

Writes under ``RUN_DIR/compare/<suite name>/`` (``<suite name>-<key>/`` for a sweep):
``results.jsonl`` (resumable as ``imitate eval``'s), ``compare.json``, ``compare.md`` (the
tables) and ``compare.png``.
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

import numpy as np
from matplotlib.figure import Figure
from scipy import stats

from imitate.errors import ImitateError
from imitate.evaluation.inference import ed50, mean_ci, teacher_effect
from imitate.evaluation.report import MARGIN, wilson
from imitate.evaluation.suite import KEYS, Suite
from imitate.evaluation.suite_run import RESULTS, Draw, check_counts, draw_jobs, run_jobs
from imitate.evaluation.teachers import check_run, teachers
from imitate.figures import plots
from imitate.motion import SIMILARITIES
from imitate.rundir.artifacts import refuse_link, save_bytes, save_json, write_atomic
from imitate.rundir.lock import locked
from imitate.stages import provenance

__all__ = [
    "compare", "dose", "markdown", "out_folder", "paired", "parse_sweep", "settings_digest",
]

log = logging.getLogger(__name__)

TEACHERS = 10  # teachers a comparison uses unless told: the unit of its inference
# The paired measures compared teacher by teacher (each teacher's mean over its variations):
# success, the pour of the worst replay, the Mahalanobis deviation from the demonstrations.
MEASURES = ("success_rate", "pour_min", "mahalanobis_rms")


def parse_sweep(text: str) -> tuple[str, tuple[float, ...]]:
    """``KEY=V1,V2,...`` as the key and its increasing values.

    Raises:
        ImitateError: not of that form, a key that is not a numeric suite key, or values that
            are not increasing numbers the key accepts.
    """
    key, _, values = text.partition("=")
    numeric = [k for k, v in KEYS.items() if not (v.is_name or v.is_switch or v.integer)
               and v.choices is None]
    refused = f"sweep={text!r} not accepted: KEY=V1,V2,... with KEY one of {numeric} and " \
              "two or more increasing values, e.g. path_length_weight=10,20,40,70"
    if key not in numeric:
        raise ImitateError(refused)
    try:
        levels = tuple(float(v) for v in values.split(","))
    except ValueError:
        raise ImitateError(refused) from None
    if len(levels) < 2 or any(b <= a for a, b in itertools.pairwise(levels)):
        raise ImitateError(refused)
    k = KEYS[key]
    outside = [v for v in levels if not k.low <= v <= k.high]
    if outside:
        raise ImitateError(
            f"sweep={text!r} not accepted: {key} {outside[0]:g} is outside {k.low:g}.."
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
) -> dict:
    """Plan and replay ``n`` variations of ``suite`` (drawn with ``seed``) with each of
    ``similarities``, for ``n_teachers`` teachers of ``run_dir`` (the run's own first; their
    models are shared with ``imitate eval``'s, under ``eval/teachers/``), at every level of
    ``sweep`` (a key and its values, :func:`parse_sweep`) if given; ``name`` names the output
    folder. Returns ``compare.json``'s contents.

    Raises:
        ImitateError: an unknown or repeated weighting, fewer than two, or what
            :func:`~imitate.evaluation.suite_run.evaluate` refuses.
    """
    similarities = tuple(similarities)
    unknown = [s for s in similarities if s not in SIMILARITIES]
    if unknown or len(set(similarities)) != len(similarities) or len(similarities) < 2:
        raise ImitateError(
            f"similarities={','.join(similarities)!r} not accepted: two or more of "
            f"{', '.join(SIMILARITIES)}, each once"
        )
    levels = [suite] if sweep is None else [suite.replace(**{sweep[0]: v}) for v in sweep[1]]
    start = time.perf_counter()
    run_dir = check_run(run_dir)
    with locked(run_dir, f"imitate compare {run_dir}"):
        n, workers = check_counts(suite, n, workers)
        out = out_folder(run_dir, name, sweep and sweep[0])
        for inside in (out, out / RESULTS):
            refuse_link(inside)
        out.mkdir(parents=True, exist_ok=True)
        models = teachers(run_dir, run_dir / "eval", n_teachers)
        code, model_bytes = provenance.code_digest(), {t.seed: t.model_bytes for t in models}
        drawn: dict[tuple[int, str], list[Draw]] = {}
        places: dict = {}  # each teacher's weight-0 path and pour, the same at every level
        for i, level in enumerate(levels):
            base = draw_jobs(models, level, seed, n, places)
            for s in similarities:
                drawn[i, s] = [
                    Draw(
                        d.teacher,
                        level.replace(similarity=s).digest(seed, model_bytes[d.teacher], code),
                        d.path, tuple(dataclasses.replace(v, similarity=s) for v in d.variations),
                    )
                    for d in base
                ]
        everything = [d for draws in drawn.values() for d in draws]
        log.info("compare: %d weightings x %d teachers x %d variations%s", len(similarities),
                 len(models), n, "" if sweep is None else f" x {len(levels)} levels")
        records, run = run_jobs(out / RESULTS, everything, models, workers, ray, progress)
        compared = [
            paired({
                s: [records[(d.digest, v.id)] for d in drawn[i, s] for v in d.variations]
                for s in similarities
            })
            for i in range(len(levels))
        ]
        result = {
            "suite_name": name, "suite": suite.to_json(), "seed": seed,
            "teachers": [t.seed for t in models], "variations_per_teacher": n,
        }
        if sweep is None:
            result.update(compared[0])
            figure = plot_comparison(result)
        else:
            result.update(sweep={"key": sweep[0], "values": list(sweep[1])}, levels=compared,
                          dose=dose(sweep[1], compared))
            figure = plot_dose(result)
        result["run"] = {**run, "command_seconds": time.perf_counter() - start}
        save_json(out / "compare.json", result)
        write_atomic(out / "compare.md", lambda tmp: tmp.write_text(markdown(result) + "\n"))
        save_bytes(out / "compare.png", plots.figure_png(figure))
        return result


def settings_digest(record: dict) -> str:
    """A record's settings but its weighting (equal for the same variation in every
    weighting)."""
    settings = {k: v for k, v in record["settings"].items() if k != "similarity"}
    text = json.dumps({"teacher": record["teacher"], **settings}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def paired(by_weighting: dict[str, list[dict]]) -> dict:
    """Per weighting (its records, in the same order for every weighting): success over
    teachers (mean, t interval) and over all variations (Wilson interval), and per teacher its
    success rate, mean pour, median Mahalanobis deviation and median clearance, and how many
    plans the null-space push changed and had fixtures; per pair: the
    teacher-level effect of each of :data:`MEASURES`
    (:func:`~imitate.evaluation.inference.teacher_effect`), the McNemar test within these
    models, and the descriptive pour-phase change.

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
    weightings = {}
    for s, rs in by_weighting.items():
        ok = [r["outcome"] == "success" for r in rs]
        change = {k: np.array([r["change"][k] for r in rs]) for k in ("pour_m", "pour_deg",
                                                                      "low_variance_m")}
        by_teacher = _by_teacher(rs)
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
            "pour_min_mean": float(np.mean([r["pour_min"] for r in rs])),
            "mahalanobis_rms_median": float(np.median([r["mahalanobis"]["rms"] for r in rs])),
            "clearance_median_mm": float(np.median([r["plan"]["min_distance_m"] for r in rs]))
            * 1000,
            "pour_error_median_mm": float(np.median([r["plan"]["pour_phase_err_m"] for r in rs]))
            * 1000,
            "pour_change_mm": _spread(change["pour_m"] * 1000),
            "pour_change_deg": _spread(change["pour_deg"]),
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
        moved = (np.array([r["change"]["pour_m"] for r in ra])
                 - np.array([r["change"]["pour_m"] for r in rb])) * 1000
        pairs.append({
            "a": a, "b": b,
            "teacher_level": {
                m: teacher_effect(np.array([ta[t][m] - tb[t][m] for t in ta])) for m in MEASURES
            },
            "within_models": {
                "both": int(np.sum(sa & sb)), "only_a": only_a, "only_b": only_b,
                "neither": int(np.sum(~sa & ~sb)), "mcnemar_p": float(mcnemar),
            },
            "pour_change_median_difference_mm": float(np.median(moved)),
        })
    return {"weightings": weightings, "pairs": pairs}


def dose(values: Sequence[float], levels: Sequence[dict]) -> dict:
    """The dose response of a sweep: per weighting, at every level (``values``, their
    :func:`paired` results ``levels``) the mean over teachers of the success rate and of the
    mean pour with their t intervals, the median Mahalanobis deviation, pour-phase error (the
    plan's largest relative position error from the GMR mean there) and clearance; its ED50
    (:func:`~imitate.evaluation.inference.ed50`; success rising or falling with the level as
    all weightings' mean curves do together; beyond the levels as ``">300"`` or ``"<10"``);
    per teacher the first level whose plans keep the margin (``">L"``: none). Per pair: how
    many teachers' ED50 or first clearing level is surely at least twice as high with ``b`` as
    with ``a``, or with ``a`` as with ``b`` (a level beyond the sweep counts as a bound), and
    how many cannot be told."""
    x = np.asarray(values, float)
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
        pours, clear = per_teacher(s, "pour_min"), per_teacher(s, "clearance_median_mm")
        found = ed50(x, rates[s], rising)
        kept = clear >= MARGIN * 1000
        totals = {k: [level["weightings"][s][k] for level in levels] for k in
                  ("mahalanobis_rms_median", "pour_error_median_mm", "clearance_median_mm")}
        curves[s] = {
            "success": [_band(rates[s][:, j]) for j in range(len(x))],
            "pour": [_band(pours[:, j]) for j in range(len(x))],
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


def markdown(result: dict) -> str:
    """``compare.md``: the weightings' table and the pairs' tests, or the sweep's tables."""
    n = result["variations_per_teacher"]
    teachers_ = ", ".join(str(t) for t in result["teachers"])
    head = (f"Suite `{result['suite_name']}`, {_count(n, 'variation')} x "
            f"{_count(len(result['teachers']), 'teacher')} (teacher seeds {teachers_}; "
            f"variation seed {result['seed']}), paired.")
    if "sweep" in result:
        return "\n".join([head, "", *_sweep_tables(result)])
    return "\n".join([head, "", *_tables(result)])


def _tables(result: dict) -> list[str]:
    """The markdown tables of one comparison (:func:`paired`'s result)."""
    lines = [
        "| weighting | success over teachers, mean [95 % t] | per teacher | all variations "
        "(Wilson 95 %, these models) | mean pour (worst replay) | Mahalanobis deviation, "
        "median [sd] | pour-phase change median / p95 [mm] | [deg] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s, w in result["weightings"].items():
        low, high = w["success_wilson95"]
        per = ", ".join(f"{t['success']}/{t['variations']}" for t in w["by_teacher"].values())
        pour, deg = w["pour_change_mm"], w["pour_change_deg"]
        lines.append(
            f"| {s} | {_percent(w['success_over_teachers'])} | {per} "
            f"| {w['success']}/{w['variations']} ({low:.3f}..{high:.3f}) "
            f"| {w['pour_min_mean']:.3f} | {w['mahalanobis_rms_median']:.2f} "
            f"| {pour['median']:.1f} / {pour['p95']:.1f} | {deg['median']:.1f} / "
            f"{deg['p95']:.1f} |"
        )
    if any(w["pushed"] for w in result["weightings"].values()):
        lines += ["", "Plans the null-space push changed (the attractors alone kept less than the "
                  "margin): " + ", ".join(f"{s} {w['pushed']}/{w['variations']}"
                                          for s, w in result["weightings"].items()) + "."]
    fixtures = next(iter(result["weightings"].values()))["fixtures"]
    if any(fixtures.values()):
        lines += ["", "Fixtures: " + ", ".join(f"a {f} in {k} variations"
                                               for f, k in fixtures.items() if k)
                  + " (one that would touch the robot at the start is left out)."]
    lines += [
        "",
        "Teacher level (each teacher one paired difference a - b; mean [95 % t interval over "
        "teachers], teachers a higher / b higher, exact permutation p):",
        "",
        "| pair (a vs b) | success [pp] | p | mean pour | p | Mahalanobis deviation [sd] | p |",
        "|---|---|---|---|---|---|---|",
    ]
    for p in result["pairs"]:
        cells = []
        for m, scale in (("success_rate", 100), ("pour_min", 1), ("mahalanobis_rms", 1)):
            e = p["teacher_level"][m]
            cells += [_effect(e, scale), _p(e["p"])]
        lines.append(f"| {p['a']} vs {p['b']} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "Within these models (variations pooled, so not evidence beyond the teachers drawn):",
        "",
        "| pair (a vs b) | both succeed | only a | only b | neither | McNemar p (exact) "
        "| pour-phase change, median a - b [mm] |",
        "|---|---|---|---|---|---|---|",
    ]
    for p in result["pairs"]:
        w = p["within_models"]
        lines.append(
            f"| {p['a']} vs {p['b']} | {w['both']} | {w['only_a']} | {w['only_b']} "
            f"| {w['neither']} | {_p(w['mcnemar_p'])} "
            f"| {p['pour_change_median_difference_mm']:+.1f} |"
        )
    return lines


def _sweep_tables(result: dict) -> list[str]:
    """The markdown tables of a sweep: the dose response, ED50, first clearing level, and each
    level's teacher-level success differences."""
    key, values = result["sweep"]["key"], result["sweep"]["values"]
    curves = result["dose"]["weightings"]
    names = list(curves)
    lines = [
        f"Success over teachers, mean [95 % t interval] and mean pour, against `{key}` (success "
        f"{'rising' if result['dose']['rising'] else 'falling'} with it):",
        "",
        f"| {key} | " + " | ".join(names) + " |",
        "|---|" + "---|" * len(names),
    ]
    for j, v in enumerate(values):
        cells = [
            f"{_percent(curves[s]['success'][j])} · {curves[s]['pour'][j]['mean']:.2f}"
            for s in names
        ]
        lines.append(f"| {v:g} | " + " | ".join(cells) + " |")
    lines += [
        "",
        f"| weighting | ED50 [95 % bootstrap over teachers] | ED50 per teacher "
        f"| first `{key}` whose plans keep the {MARGIN * 1000:.0f} mm margin, per teacher |",
        "|---|---|---|---|",
    ]
    for s in names:
        c = curves[s]
        ci = c["ed50_ci95"]
        interval = f" [{_show(ci[0])}, {_show(ci[1])}]" if ci else ""
        lines.append(
            f"| {s} | {_show(c['ed50'])}{interval} "
            f"| {', '.join(_show(v) for v in c['ed50_by_teacher'].values())} "
            f"| {', '.join(_show(v) for v in c['first_clear_by_teacher'].values())} |"
        )
    lines += [
        "",
        "Teachers whose level is surely at least twice as high with b as with a / with a as "
        "with b (a level beyond the sweep counts as a bound) / not known:",
        "",
        "| pair (a vs b) | ED50 | first level keeping the margin |",
        "|---|---|---|",
    ]
    for p in result["dose"]["pairs"]:
        cells = [f"{p[w]['b_twice_a']} / {p[w]['a_twice_b']} / {p[w]['untold']}"
                 for w in ("ed50", "first_clear")]
        lines.append(f"| {p['a']} vs {p['b']} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "Success difference a - b per level [pp], mean [95 % t interval over teachers] "
        "(permutation p, each level and pair on its own: not corrected for the tests made):",
        "",
        "| pair (a vs b) | " + " | ".join(f"{key} {v:g}" for v in values) + " |",
        "|---|" + "---|" * len(values),
    ]
    for i, p in enumerate(result["levels"][0]["pairs"]):
        cells = [
            f"{_effect(level['pairs'][i]['teacher_level']['success_rate'], 100, counts=False)} "
            f"({_p(level['pairs'][i]['teacher_level']['success_rate']['p'])})"
            for level in result["levels"]
        ]
        lines.append(f"| {p['a']} vs {p['b']} | " + " | ".join(cells) + " |")
    return lines


def plot_comparison(result: dict) -> Figure:
    """Success per weighting over teachers (bar: the mean, 95 % t interval; dots: each
    teacher), and per pair the teacher-level differences of success and of the mean pour with
    their t intervals (dots: each teacher's difference)."""
    figure = Figure(figsize=(15, 5.2), layout="constrained")
    left, middle, right = figure.subplots(1, 3)
    names = list(result["weightings"])
    positions = np.arange(len(names))
    weightings = [result["weightings"][s] for s in names]
    bands = [w["success_over_teachers"] for w in weightings]
    rates = np.array([b["mean"] for b in bands])
    bounds = np.array([np.clip(b["ci95"], 0, 1) if b["ci95"] else [b["mean"]] * 2
                       for b in bands])
    left.bar(positions, rates, color="0.85", edgecolor="0.3")
    errors = np.clip([rates - bounds[:, 0], bounds[:, 1] - rates], 0.0, None)
    left.errorbar(positions, rates, yerr=errors, fmt="none", color="k", capsize=6)
    teacher_list = [str(t) for t in result["teachers"]]
    for j, teacher in enumerate(teacher_list):
        offset = 0.3 * (j + 0.5) / len(teacher_list) - 0.15
        left.plot(positions + offset, [w["by_teacher"][teacher]["success_rate"]
                                       for w in weightings], "o", color=f"C{j % 10}", ms=4)
    left.set(xticks=positions, ylim=(0, 1.05), ylabel="success rate",
             title="success: mean over teachers, 95 % t\n(dots: teachers)")
    left.set_xticklabels(names, rotation=30, ha="right")
    pairs = result["pairs"]
    for axis, measure, scale, label in (
        (middle, "success_rate", 100, "success difference a - b [pp]"),
        (right, "pour_min", 1, "mean pour difference a - b"),
    ):
        for i, p in enumerate(pairs):
            e = p["teacher_level"][measure]
            ta = result["weightings"][p["a"]]["by_teacher"]
            tb = result["weightings"][p["b"]]["by_teacher"]
            d = [scale * (ta[t][measure] - tb[t][measure]) for t in ta]
            axis.plot(d, np.full(len(d), i) + np.linspace(-0.15, 0.15, len(d)), "o",
                      color="0.6", ms=3)
            if e["ci95"] is not None:
                axis.plot([scale * v for v in e["ci95"]], [i, i], color="k", lw=2)
            axis.plot([scale * e["mean"]], [i], "D", color="k", ms=6)
        axis.axvline(0, color="0.4", lw=0.8, ls="--")
        axis.set(yticks=np.arange(len(pairs)), yticklabels=[f"{p['a']} vs {p['b']}"
                                                           for p in pairs],
                 xlabel=label, title="mean over teachers, 95 % t\n(dots: teachers)")
        axis.invert_yaxis()
    figure.suptitle(
        f"suite {result['suite_name']}: {_count(result['variations_per_teacher'], 'variation')}"
        f" x {_count(len(result['teachers']), 'teacher')}, the same for every weighting"
    )
    return figure


def plot_dose(result: dict) -> Figure:
    """Success and mean pour against the swept level per weighting (bands: 95 % t intervals
    over teachers; dotted: ED50), and the Pareto view: the plans' clearance against their
    pour-phase error, one point per level."""
    figure = Figure(figsize=(15, 4.8), layout="constrained")
    left, middle, right = figure.subplots(1, 3)
    key, x = result["sweep"]["key"], np.asarray(result["sweep"]["values"], float)
    log_x = bool(np.all(x > 0))
    for i, (s, c) in enumerate(result["dose"]["weightings"].items()):
        colour = f"C{i}"
        for axis, which in ((left, "success"), (middle, "pour")):
            mean = np.array([b["mean"] for b in c[which]])
            band = np.clip([b["ci95"] or [b["mean"]] * 2 for b in c[which]], 0.0, 1.0)
            axis.plot(x, mean, "o-", color=colour, label=s)
            axis.fill_between(x, band[:, 0], band[:, 1], color=colour, alpha=0.15)
        if isinstance(c["ed50"], float):
            left.axvline(c["ed50"], color=colour, ls=":", lw=1)
        right.plot(c["pour_error_median_mm"], c["clearance_median_mm"], "o-", color=colour,
                   label=s)
        for v, m, d in zip(x, c["pour_error_median_mm"], c["clearance_median_mm"],
                           strict=True):
            right.annotate(f"{v:g}", (m, d), fontsize=7, color=colour,
                           xytext=(3, 3), textcoords="offset points")
    for axis, label in ((left, "success rate"), (middle, "mean pour (worst replay)")):
        axis.set(xlabel=key, ylabel=label, ylim=(-0.02, 1.05), xscale="log" if log_x else "linear")
        axis.set_xticks(x, [f"{v:g}" for v in x])  # the swept values, not powers of ten
        axis.set_xticks([], minor=True)
    left.axhline(0.5, color="0.5", lw=0.8)
    left.set_title("success (bands: 95 % over teachers; dotted: ED50)")
    middle.set_title("pour")
    left.legend(fontsize=8)
    right.axhline(MARGIN * 1000, color="0.5", lw=0.8, ls="--")
    right.set(xlabel="pour-phase error of the plan, median [mm]",
              ylabel="plan clearance, median [mm]",
              title=f"clearance against the task\n(labels: {key}; dashed: the margin)")
    figure.suptitle(
        f"suite {result['suite_name']} swept over {key}: "
        f"{_count(result['variations_per_teacher'], 'variation')} x "
        f"{_count(len(result['teachers']), 'teacher')} per level and weighting"
    )
    return figure


def _count(n: int, noun: str) -> str:
    """``"1 teacher"``, ``"3 teachers"``."""
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _by_teacher(records: Sequence[dict]) -> dict[str, dict]:
    """Per teacher (its seed as text): variations, successes, the success rate, the mean pour,
    the median Mahalanobis deviation and the median plan clearance [mm]."""
    groups: dict[str, list[dict]] = {}
    for r in records:
        groups.setdefault(str(r["teacher"]), []).append(r)
    return {
        t: {
            "variations": len(rs), "success": sum(r["outcome"] == "success" for r in rs),
            "success_rate": sum(r["outcome"] == "success" for r in rs) / len(rs),
            "pour_min": float(np.mean([r["pour_min"] for r in rs])),
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


def _show(value: float | str | None) -> str:
    if value is None:
        return "none"
    if isinstance(value, str):
        return value
    return f"{value:.4g}" if value < 1e4 else f"{value:.0f}"


def _percent(band: dict) -> str:
    """A success band in percent, its interval clipped to 0..100."""
    ci = band["ci95"]
    inside = (f" [{100 * max(ci[0], 0.0):.0f}, {100 * min(ci[1], 1.0):.0f}]" if ci else "")
    return f"{100 * band['mean']:.0f} %{inside}"


def _effect(e: dict, scale: float, counts: bool = True) -> str:
    """A teacher-level effect: mean [interval] and, with ``counts``, teachers a / b higher;
    ``scale`` 100 for success rates in points (their interval clipped to -100..100)."""
    ci = e["ci95"] and (np.clip(e["ci95"], -1.0, 1.0) if scale == 100 else e["ci95"])
    digits = 1 if scale != 1 else 3
    text = f"{scale * e['mean']:+.{digits}f}"
    if ci is not None:
        text += f" [{scale * ci[0]:+.{digits}f}, {scale * ci[1]:+.{digits}f}]"
    if counts:
        text += f", {e['a_higher']}/{e['b_higher']}"
    return text


def _spread(values: np.ndarray) -> dict[str, float]:
    return {"median": float(np.median(values)), "p95": float(np.percentile(values, 95)),
            "max": float(values.max())}


def _p(p: float | None) -> str:
    if p is None:
        return "n/a"
    return f"{p:.2g}" if p >= 1e-4 else f"{p:.1e}"
