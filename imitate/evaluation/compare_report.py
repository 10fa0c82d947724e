"""What ``imitate compare`` writes for people: ``compare.md`` (the tables) and ``compare.png``
(the figure) of a comparison of similarity weightings or of a sweep
(:func:`~imitate.evaluation.compare.compare`'s result). The words and keys named after the
task's score and critical phase are the run's task's (``Task.score``, ``Task.phase``).
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from imitate.envs.task import Task
from imitate.evaluation.record import score_keys
from imitate.evaluation.report import MARGIN

__all__ = ["markdown", "measures", "plot_comparison", "plot_dose"]


def measures(task: Task) -> tuple[str, str, str]:
    """The paired measures compared teacher by teacher (each teacher's mean over its
    variations): success, the task's score of the worst replay (``<score>_min``), the
    Mahalanobis deviation from the demonstrations."""
    return "success_rate", score_keys(task)[1], "mahalanobis_rms"


# What each weighting's total weight is matched to (:func:`~imitate.motion.costs.weighting`):
# one rule per kind, so that a difference is where the weight sits, not how much there is.
_PER_DIMENSION = "eq. 21's per dimension"
_OVERALL = ("eq. 21's over all dimensions, each counted as its stiffness when the others adjust "
            "(tolerance units)")
BUDGET = {
    "variance": "eq. 21's", "uniform": _PER_DIMENSION, "inverted": _PER_DIMENSION,
    "inverse_variance": _PER_DIMENSION, "oracle": _PER_DIMENSION, "precision": _OVERALL,
    "importance": "eq. 21's outside the critical phase; inside it, " + _OVERALL,
}


def markdown(result: dict, task: Task) -> str:
    """``compare.md`` of a comparison of ``task``: the weightings' table and the pairs' tests,
    or the sweep's tables."""
    n = result["variations_per_teacher"]
    teachers_ = ", ".join(str(t) for t in result["teachers"])
    head = (f"Suite `{result['suite_name']}`, {_count(n, 'variation')} x "
            f"{_count(len(result['teachers']), 'teacher')} (teacher seeds {teachers_}; "
            f"variation seed {result['seed']}), paired.")
    weightings = result["weightings"] if "weightings" in result else result["levels"][0][
        "weightings"]
    head += " Total weight (" + "; ".join(f"{w}: {BUDGET[w]}" for w in weightings) + ")."
    if "sweep" in result:
        return "\n".join([head, "", *_sweep_tables(result, task)])
    primary = [*_primary(result["replication"]), ""] if "replication" in result else []
    return "\n".join([head, "", *primary, *_tables(result, task)])


def _primary(replication: dict) -> list[str]:
    """The primary endpoint per block of teachers, its power line and clustered model, and
    whether the development verdict replicated."""
    lines = [
        f"Primary endpoint, declared before the runs: **{replication['endpoint']}**. Verdict: "
        f"**{replication['verdict']}** (the confirmation block repeats the development "
        "block's sign with an interval excluding 0).",
        "",
        "| teachers | seeds | a, b success | a - b [pp], mean [95 % t], a / b higher "
        "| permutation p (floor) "
        "| smallest detectable [pp] (80 % power) | teachers needed for this mean "
        "| GEE odds ratio a/b [95 %], p (teacher clusters) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name in ("development", "confirmation", "all"):
        block = replication[name]
        if block is None:
            continue
        seeds, power, gee = block["teachers"], block["power"], block["gee"]
        floor = f"{_p(power['permutation_floor'])}" + (
            ", above 0.05: cannot decide" if power["floor_above_level"] else ""
        )
        detectable = power["detectable"]
        detectable = "n/a" if detectable is None else (
            ">100" if detectable > 1 else f"{100 * detectable:.1f}")
        odds = gee["note"] or (
            f"{gee['odds_ratio']:.2f} [{gee['ci95'][0]:.2f}, {gee['ci95'][1]:.2f}], "
            f"{_p(gee['p'])}"
        )
        lines.append(
            f"| {name} ({len(seeds)}) | {_seeds(seeds)} | "
            + " / ".join(f"{100 * v:.0f} %" for v in block["success"].values())
            + f" | {_effect(block['effect'], 100)} "
            f"| {_p(block['effect']['p'])} ({floor}) "
            f"| {detectable} "
            f"| {power['teachers_needed'] or 'n/a'} | {odds} |"
        )
    return lines


def _seeds(seeds: list[int]) -> str:
    """Sorted seeds with each run of three or more consecutive ones as a range: ``0-9,
    1000-1014``."""
    runs: list[list[int]] = []
    for seed in seeds:
        if runs and seed == runs[-1][-1] + 1:
            runs[-1].append(seed)
        else:
            runs.append([seed])
    return ", ".join(f"{r[0]}-{r[-1]}" if len(r) > 2 else ", ".join(map(str, r)) for r in runs)


def _tables(result: dict, task: Task) -> list[str]:
    """The markdown tables of one comparison (:func:`paired`'s result)."""
    phase, min_key = task.phase, score_keys(task)[1]
    lines = [
        "| weighting | success over teachers, mean [95 % t] | per teacher | all variations "
        f"(Wilson 95 %, these models) | mean {task.score.label} (worst replay) | Mahalanobis "
        "deviation, "
        f"median [sd] | {phase}-phase change median / p95 [mm] | [deg] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s, w in result["weightings"].items():
        low, high = w["success_wilson95"]
        per = ", ".join(f"{t['success']}/{t['variations']}" for t in w["by_teacher"].values())
        moved, deg = w[f"{phase}_change_mm"], w[f"{phase}_change_deg"]
        lines.append(
            f"| {s} | {_percent(w['success_over_teachers'])} | {per} "
            f"| {w['success']}/{w['variations']} ({low:.3f}..{high:.3f}) "
            f"| {task.score.show(w[f'{min_key}_mean'])} | {w['mahalanobis_rms_median']:.2f} "
            f"| {moved['median']:.1f} / {moved['p95']:.1f} | {deg['median']:.1f} / "
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
        f"| pair (a vs b) | success [pp] | p | mean {task.score.label} | p | Mahalanobis "
        "deviation [sd] "
        "| p |",
        "|---|---|---|---|---|---|---|",
    ]
    for p in result["pairs"]:
        cells = []
        for m, scale in zip(measures(task), (100, task.score.scale, 1), strict=True):
            e = p["teacher_level"][m]
            cells += [_effect(e, scale), _p(e["p"])]
        lines.append(f"| {p['a']} vs {p['b']} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "Within these models (variations pooled, so not evidence beyond the teachers drawn):",
        "",
        "| pair (a vs b) | both succeed | only a | only b | neither | McNemar p (exact) "
        f"| {phase}-phase change, median a - b [mm] |",
        "|---|---|---|---|---|---|---|",
    ]
    for p in result["pairs"]:
        w = p["within_models"]
        lines.append(
            f"| {p['a']} vs {p['b']} | {w['both']} | {w['only_a']} | {w['only_b']} "
            f"| {w['neither']} | {_p(w['mcnemar_p'])} "
            f"| {p[f'{phase}_change_median_difference_mm']:+.1f} |"
        )
    return lines


def _sweep_tables(result: dict, task: Task) -> list[str]:
    """The markdown tables of a sweep: the dose response, ED50, first clearing level, and each
    level's teacher-level success differences."""
    key, values = result["sweep"]["key"], result["sweep"]["values"]
    curves, score = result["dose"]["weightings"], task.score.name
    show = task.score.show
    names = list(curves)
    lines = [
        f"Success over teachers, mean [95 % t interval] and mean {task.score.label}, against "
        f"`{key}` "
        "(success "
        f"{'rising' if result['dose']['rising'] else 'falling'} with it):",
        "",
        f"| {key} | " + " | ".join(names) + " |",
        "|---|" + "---|" * len(names),
    ]
    for j, v in enumerate(values):
        cells = [
            f"{_percent(curves[s]['success'][j])} · {show(curves[s][score][j]['mean'])}"
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


def plot_comparison(result: dict, task: Task) -> Figure:
    """Success per weighting over teachers (bar: the mean, 95 % t interval; dots: each
    teacher), and per pair the teacher-level differences of success and of the mean score of
    ``task`` with their t intervals (dots: each teacher's difference)."""
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
    for position, band, bound in zip(positions, bands, bounds, strict=True):
        for end, marker in ((0, "v"), (1, "^")):  # an interval cut at 0 or 1: marked
            if band["ci95"] and band["ci95"][end] != bound[end]:
                left.plot(position, bound[end], marker, color="k", ms=7, clip_on=False)
    teacher_list = [str(t) for t in result["teachers"]]
    for j, teacher in enumerate(teacher_list):
        offset = 0.3 * (j + 0.5) / len(teacher_list) - 0.15
        left.plot(positions + offset, [w["by_teacher"][teacher]["success_rate"]
                                       for w in weightings], "o", color=f"C{j % 10}", ms=4,
                  clip_on=False, zorder=3, label=f"teacher {teacher}")  # dots at 0 shown whole
    left.set(xticks=positions, ylim=(0, 1.05), ylabel="success rate",
             title="success: mean over teachers, 95 % t\n(dots: teachers; triangles: cut at "
             "0 or 1)")
    left.legend(fontsize=6, ncol=max(1, len(teacher_list) // 10), loc="upper left",
                bbox_to_anchor=(1.0, 1.0), frameon=False)
    left.set_xticklabels(names, rotation=30, ha="right")
    pairs = result["pairs"]
    for axis, measure, scale, label in (
        (middle, "success_rate", 100, "success difference a - b [pp]"),
        (right, score_keys(task)[1], task.score.scale,
         f"mean {task.score.label} difference a - b"),
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


def plot_dose(result: dict, task: Task) -> Figure:
    """Success and mean score of ``task`` against the swept level per weighting (bands: 95 % t
    intervals over teachers; dotted: ED50), and the Pareto view: the plans' clearance against
    their critical phase's error, one point per level."""
    score, error = task.score.name, f"{task.phase}_error_median_mm"
    figure = Figure(figsize=(15, 4.8), layout="constrained")
    left, middle, right = figure.subplots(1, 3)
    key, x = result["sweep"]["key"], np.asarray(result["sweep"]["values"], float)
    log_x = bool(np.all(x > 0))
    for i, (s, c) in enumerate(result["dose"]["weightings"].items()):
        colour = f"C{i}"
        for axis, which, scale in ((left, "success", 1.0), (middle, score, task.score.scale)):
            mean = scale * np.array([b["mean"] for b in c[which]])
            band = scale * np.array([b["ci95"] or [b["mean"]] * 2 for b in c[which]])
            if which == "success" or not task.score.unit:  # a fraction: 0..1
                band = np.clip(band, 0.0, 1.0)
            axis.plot(x, mean, "o-", color=colour, label=s)
            axis.fill_between(x, band[:, 0], band[:, 1], color=colour, alpha=0.15)
        if isinstance(c["ed50"], float):
            left.axvline(c["ed50"], color=colour, ls=":", lw=1)
        right.plot(c[error], c["clearance_median_mm"], "o-", color=colour, label=s)
        for v, m, d in zip(x, c[error], c["clearance_median_mm"], strict=True):
            right.annotate(f"{v:g}", (m, d), fontsize=7, color=colour,
                           xytext=(3, 3), textcoords="offset points")
    for axis, label in ((left, "success rate"),
                        (middle, f"mean {task.score.label} (worst replay)")):
        axis.set(xlabel=key, ylabel=label, xscale="log" if log_x else "linear")
        if axis is left or not task.score.unit:
            axis.set_ylim(-0.02, 1.05)
        axis.set_xticks(x, [f"{v:g}" for v in x])  # the swept values, not powers of ten
        axis.set_xticks([], minor=True)
    left.axhline(0.5, color="0.5", lw=0.8)
    left.set_title("success (bands: 95 % over teachers; dotted: ED50)")
    middle.set_title(score)
    left.legend(fontsize=8)
    right.axhline(MARGIN * 1000, color="0.5", lw=0.8, ls="--")
    right.set(xlabel=f"{task.phase}-phase error of the plan, median [mm]",
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


def _p(p: float | None) -> str:
    if p is None:
        return "n/a"
    return f"{p:.2g}" if p >= 1e-4 else f"{p:.1e}"
