"""``imitate compare``: similarity weightings on the same variations, paired.

Every weighting plans and replays the same variations of a suite (the same settings but
``similarity``) with the learned models of the same teachers, so that each pair of weightings
is compared variation by variation: an exact McNemar test on success (the variations where one
succeeds and the other fails) and a Wilcoxon signed-rank test on how far the constraints moved
the pour (``change.pour_m``, from each weighting's own unconstrained reproduction).

Writes under ``RUN_DIR/compare/<suite name>/``: ``results.jsonl`` (resumable as ``imitate
eval``'s), ``compare.json``, ``compare.md`` (the tables) and ``compare.png``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import itertools
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from scipy import stats

from imitate.errors import ImitateError
from imitate.evaluation.evaluate import RESULTS, Draw, check_counts, draw_jobs, run_jobs
from imitate.evaluation.report import wilson
from imitate.evaluation.suite import Suite
from imitate.evaluation.teachers import check_run, teachers
from imitate.figures import plots
from imitate.motion import SIMILARITIES
from imitate.rundir.artifacts import refuse_link, save_json, write_atomic
from imitate.rundir.lock import locked
from imitate.stages import provenance

__all__ = ["compare", "markdown", "paired", "settings_digest"]


def compare(
    run_dir: Path,
    suite: Suite,
    similarities: Sequence[str],
    *,
    name: str = "default",
    n: int | None = None,
    seed: int = 0,
    n_teachers: int = 3,
    workers: int | None = None,
    ray: str | None = None,
    progress: bool | None = None,
) -> dict:
    """Plan and replay ``n`` variations of ``suite`` (drawn with ``seed``) with each of
    ``similarities``, for ``n_teachers`` teachers of ``run_dir`` (the run's own first; their
    models are shared with ``imitate eval``'s, under ``eval/teachers/``); ``name`` names the
    output folder. Returns ``compare.json``'s contents.

    Raises:
        ImitateError: an unknown or repeated weighting, fewer than two, or what
            :func:`~imitate.evaluation.evaluate.evaluate` refuses.
    """
    similarities = tuple(similarities)
    unknown = [s for s in similarities if s not in SIMILARITIES]
    if unknown or len(set(similarities)) != len(similarities) or len(similarities) < 2:
        raise ImitateError(
            f"--similarity {','.join(similarities)} not accepted: two or more of "
            f"{', '.join(SIMILARITIES)}, comma-separated, each once"
        )
    run_dir = check_run(run_dir)
    with locked(run_dir, f"imitate compare {run_dir}"):
        n, workers = check_counts(suite, n, workers)
        out = run_dir / "compare" / name
        for inside in (out, out / RESULTS):
            refuse_link(inside)
        out.mkdir(parents=True, exist_ok=True)
        models = teachers(run_dir, run_dir / "eval", n_teachers)
        base = draw_jobs(models, suite, seed, n)
        code, model_bytes = provenance.code_digest(), {t.seed: t.model_bytes for t in models}
        drawn = {
            s: [
                Draw(
                    d.teacher,
                    suite.replace(similarity=s).digest(seed, model_bytes[d.teacher], code),
                    d.path, tuple(dataclasses.replace(v, similarity=s) for v in d.variations),
                )
                for d in base
            ]
            for s in similarities
        }
        everything = [d for s in similarities for d in drawn[s]]
        records, run = run_jobs(out / RESULTS, everything, models, workers, ray, progress)
        by_weighting = {
            s: [records[(d.digest, v.id)] for d in drawn[s] for v in d.variations]
            for s in similarities
        }
        result = {
            "suite_name": name, "suite": suite.to_json(), "seed": seed,
            "teachers": [t.seed for t in models], "variations_per_teacher": n,
            **paired(by_weighting), "run": run,
        }
        save_json(out / "compare.json", result)
        write_atomic(out / "compare.md", lambda tmp: tmp.write_text(markdown(result) + "\n"))
        plots.save(plot_comparison(by_weighting, result), out / "compare.png")
        return result


def settings_digest(record: dict) -> str:
    """A record's settings but its weighting (equal for the same variation in every
    weighting)."""
    settings = {k: v for k, v in record["settings"].items() if k != "similarity"}
    text = json.dumps({"teacher": record["teacher"], **settings}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def paired(by_weighting: dict[str, list[dict]]) -> dict:
    """Per weighting (its records, in the same order for every weighting): success with its
    Wilson interval, per teacher, and the task change [mm, deg]; per pair: the exact McNemar
    test on success and the Wilcoxon signed-rank test on the pour-phase change.

    Raises:
        ImitateError: the weightings' records are not of the same variations.
    """
    keys = {s: [settings_digest(r) for r in rs] for s, rs in by_weighting.items()}
    if len({tuple(k) for k in keys.values()}) != 1:
        raise ImitateError("the weightings' records are not of the same variations")
    weightings = {}
    for s, rs in by_weighting.items():
        ok = [r["outcome"] == "success" for r in rs]
        change = {k: np.array([r["change"][k] for r in rs]) for k in ("pour_m", "pour_deg",
                                                                      "low_variance_m")}
        per_teacher: dict[str, list[int]] = {}  # successes, variations
        for r, good in zip(rs, ok, strict=True):
            done = per_teacher.setdefault(str(r["teacher"]), [0, 0])
            done[0] += good
            done[1] += 1
        weightings[s] = {
            "variations": len(rs), "success": sum(ok), "success_rate": sum(ok) / len(rs),
            "success_wilson95": list(wilson(sum(ok), len(rs))),
            "success_by_teacher": per_teacher,
            "outcomes": {o: sum(r["outcome"] == o for r in rs) for o in
                         sorted({r["outcome"] for r in rs})},
            "pour_change_mm": _spread(change["pour_m"] * 1000),
            "pour_change_deg": _spread(change["pour_deg"]),
            "low_variance_change_mm": _spread(change["low_variance_m"] * 1000),
            "pour_min_mean": float(np.mean([r["pour_min"] for r in rs])),
        }
    pairs = []
    for a, b in itertools.combinations(by_weighting, 2):
        ra, rb = by_weighting[a], by_weighting[b]
        sa = np.array([r["outcome"] == "success" for r in ra])
        sb = np.array([r["outcome"] == "success" for r in rb])
        only_a, only_b = int(np.sum(sa & ~sb)), int(np.sum(~sa & sb))
        mcnemar = (
            stats.binomtest(only_a, only_a + only_b, 0.5).pvalue if only_a + only_b else 1.0
        )
        da = np.array([r["change"]["pour_m"] for r in ra]) * 1000
        db = np.array([r["change"]["pour_m"] for r in rb]) * 1000
        differences = da - db
        wilcoxon = (
            float(stats.wilcoxon(da, db).pvalue) if np.any(differences != 0) else 1.0
        )
        pairs.append({
            "a": a, "b": b, "both": int(np.sum(sa & sb)), "neither": int(np.sum(~sa & ~sb)),
            "only_a": only_a, "only_b": only_b, "mcnemar_p": float(mcnemar),
            "success_difference": float(sa.mean() - sb.mean()),
            "pour_change_median_difference_mm": float(np.median(differences)),
            "wilcoxon_p": wilcoxon,
        })
    return {"weightings": weightings, "pairs": pairs}


def markdown(result: dict) -> str:
    """``compare.md``: the weightings' table and the pairs' tests."""
    n = result["variations_per_teacher"]
    teachers_ = ", ".join(str(t) for t in result["teachers"])
    lines = [
        f"Suite `{result['suite_name']}`, {n} variations x teachers {teachers_} (seed "
        f"{result['seed']}), paired.",
        "",
        "| weighting | success | Wilson 95 % | per teacher | pour-phase change median / p95 "
        "[mm] | [deg] | change where the demonstrations agree, median / p95 [mm] |",
        "|---|---|---|---|---|---|---|",
    ]
    for s, w in result["weightings"].items():
        low, high = w["success_wilson95"]
        per = ", ".join(f"{a}/{b}" for a, b in w["success_by_teacher"].values())
        pour, deg, low_var = w["pour_change_mm"], w["pour_change_deg"], w["low_variance_change_mm"]
        lines.append(
            f"| {s} | {w['success']}/{w['variations']} | {low:.3f}..{high:.3f} | {per} "
            f"| {pour['median']:.1f} / {pour['p95']:.1f} | {deg['median']:.1f} / {deg['p95']:.1f} "
            f"| {low_var['median']:.1f} / {low_var['p95']:.1f} |"
        )
    lines += [
        "",
        "| pair (a vs b) | both succeed | only a | only b | neither | McNemar p (exact) "
        "| pour-phase change, median a - b [mm] | Wilcoxon p |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for p in result["pairs"]:
        lines.append(
            f"| {p['a']} vs {p['b']} | {p['both']} | {p['only_a']} | {p['only_b']} "
            f"| {p['neither']} | {_p(p['mcnemar_p'])} "
            f"| {p['pour_change_median_difference_mm']:+.1f} | {_p(p['wilcoxon_p'])} |"
        )
    return "\n".join(lines)


def plot_comparison(by_weighting: dict[str, list[dict]], result: dict) -> Figure:
    """Success with its Wilson interval per weighting (dots: each teacher) beside the
    distribution of the pour-phase change."""
    figure = Figure(figsize=(11, 4.5), layout="constrained")
    left, right = figure.subplots(1, 2)
    names = list(by_weighting)
    positions = np.arange(len(names))
    weightings = [result["weightings"][s] for s in names]
    rates = np.array([w["success_rate"] for w in weightings])
    bounds = np.array([w["success_wilson95"] for w in weightings])
    left.bar(positions, rates, color="0.85", edgecolor="0.3")
    left.errorbar(positions, rates, yerr=[rates - bounds[:, 0], bounds[:, 1] - rates],
                  fmt="none", color="k", capsize=6)
    for j, teacher in enumerate(result["teachers"]):
        shares = [w["success_by_teacher"][str(teacher)] for w in weightings]
        offset = 0.3 * (j + 0.5) / len(result["teachers"]) - 0.15
        left.plot(positions + offset, [a / b for a, b in shares], "o", color=f"C{j}", ms=5,
                  label=f"teacher seed {teacher}")
    left.set(xticks=positions, xticklabels=names, ylim=(0, 1.05), ylabel="success rate",
             title="success (bar: 95 % Wilson interval; dots: teachers)")
    left.legend(fontsize=8, loc="upper left")
    changes = [
        np.maximum(np.array([r["change"]["pour_m"] for r in by_weighting[s]]) * 1000, 0.1)
        for s in names
    ]
    right.boxplot(changes, positions=positions, widths=0.5, whis=(5, 95))
    right.set(xticks=positions, xticklabels=names, yscale="log",
              ylabel="largest change in the pour [mm]",
              title="pour moved from the unconstrained plan (whiskers: 5-95 %)")
    figure.suptitle(
        f"suite {result['suite_name']}: {result['variations_per_teacher']} variations x "
        f"{len(result['teachers'])} teachers, the same for every weighting"
    )
    return figure


def _spread(values: np.ndarray) -> dict[str, float]:
    return {"median": float(np.median(values)), "p95": float(np.percentile(values, 95)),
            "max": float(values.max())}


def _p(p: float) -> str:
    return f"{p:.2g}" if p >= 1e-4 else f"{p:.1e}"
