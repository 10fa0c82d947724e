"""``report.html``: the page a person opens instead of reading JSON, for a run directory
(:func:`run_page`, from its report, settings and task) or an evaluation (:func:`eval_page`, from
its summary). Self-contained: inline CSS, no script, no external resource; every figure, video
and artifact is referenced by a path relative to the page. A section whose numbers are not in
the report (a run stopped before ``replay``) is left out. The page names no task: the run's
task gives its words (:class:`Words`), its tool and its critical phase.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from html import escape
from pathlib import Path
from typing import Any

from imitate.rundir.artifacts import write_atomic
from imitate.rundir.layout import PAGE

__all__ = [
    "CAPTIONS", "Words", "error_keys", "eval_page", "run_page", "save_eval_page", "save_run_page",
    "shown",
]


@dataclass(frozen=True)
class Words:
    """What the pages and the datasets say of a task, declared with it.

    Attributes:
        verbs: The run page's verdict on a run that succeeds and on one that does not (a
            present-tense verb and its negation).
        noun: The reproduction as a noun, in the video's caption.
        instruction: What the robot is asked to do, a dataset's task (an imperative).
        headline: ``headline(replay) -> [(label, text)]``: the run page's headline rows of the
            task's numbers, from the report's replay section.
    """

    verbs: tuple[str, str]
    noun: str
    instruction: str
    headline: Callable[[Mapping[str, Any]], list[tuple[str, str]]]


def error_keys(phase: str) -> tuple[str, str]:
    """The optimization's (and a plan record's) keys of a plan's largest position [m] and angle
    [deg] error in the critical phase ``phase``."""
    return f"{phase}_phase_err_m", f"{phase}_phase_err_deg"


CAPTIONS = {  # figures/<name>.png: what it shows ({tool}: the tool's name)
    "observation": "Tracked against true object trajectories; detected demonstration boundaries.",
    "fig4_gmm_dtw": "Paper Fig. 4: GMM over time on the {tool}'s angle, without and with DTW.",
    "fig5_bic": "Paper Fig. 5: BIC against K, fast heuristic (K-means only) and full EM.",
    "gmr": "GMR mean ± 2σ per task dimension over the aligned demonstrations.",
    "fig8_snapshots": "Paper Fig. 8: the physics replays without the collision cost (top) and "
                      "with it (bottom); parts touching or penetrating are framed in red.",
    "fig9_collision_sweep": "Paper Fig. 9: the reproductions of the collision-weight sweep "
                            "against the GMR mean ± 2σ, their deviation and clearance. Orange: "
                            "steps where eq. 21 leaves a dimension less than 10 % of its weight "
                            "(near its largest variance, where the weight is 0): the plan is "
                            "nearly free there, and low collision weights clear a collision by "
                            "moving there first. The plans may leave the ±2σ band there: the "
                            "band shows where the demonstrations varied, not a bound on the "
                            "plan, and where the weight is low little pulls the plan back.",
    "costs": "Total cost per optimizer iteration, for each weight of the sweep.",
}
VIDEO_CAPTION = (  # {noun}: the task's
    "The teacher demonstrates; the robot reproduces {noun} without the collision cost, then "
    "with it, in physics."
)
CLAIM = (
    "The paper's claim: weighting the similarity to the demonstrations by their variance (eq. 21) "
    "lets the reproduction leave them where they varied, to meet a new constraint, and keeps the "
    "task where they agreed. Fig. 9 shows where this run's plan gave way as the collision weight "
    "grew, Fig. 8 the plans without and with the collision cost in physics; "
    "<code>imitate compare</code> tests the claim against other weightings."
)
LEADING_FIGURES = ("fig9_collision_sweep", "fig8_snapshots")  # the claim's, shown first
OUTCOMES_CAPTION = (
    "Obstacles on the table by outcome (filled: placed in the path), over the held objects' path "
    "at weight 0; outcome counts by where the obstacle is."
)
SHOWN_APART = {"schema", "seed", "timings", "artifacts"}  # report keys not in "All numbers"
STYLE = "".join((
    "body{font:15px/1.45 system-ui,sans-serif;color:#1f2328;max-width:1080px;margin:2em auto;",
    "padding:0 1.2em}h1{font-size:1.6em;margin:0}.sub{color:#59636e;margin:.3em 0 0}",
    "h2{font-size:1.2em;border-bottom:1px solid #d0d7de;padding-bottom:.2em;margin-top:2em}",
    "h3{font-size:1em;margin:.6em 0 .2em}table{border-collapse:collapse;margin:.3em 0}",
    "th,td{padding:.2em .9em .2em 0;text-align:left;vertical-align:top}",
    "tr+tr td{border-top:1px solid #eaeef2}th{border-bottom:2px solid #d0d7de}",
    "td.n{text-align:right;font-variant-numeric:tabular-nums}tr.chosen td{font-weight:600}",
    ".ok{color:#1a7f37;font-weight:600}.bad{color:#cf222e;font-weight:600}",
    ".row{display:flex;flex-wrap:wrap;gap:0 4em;align-items:flex-start}",
    "figure{margin:1.2em 0}img,video{max-width:100%;border:1px solid #d0d7de}",
    "figcaption{color:#59636e;font-size:.9em;margin-top:.3em}ul.files{columns:3}",
    ".grid{display:grid;grid-template-columns:repeat(auto-fill,minmax(320px,1fr));gap:0 1.5em}",
))


def run_page(
    report: dict, config: dict, run_dir: str, words: Words, tool: str, phase: str,
    outdated: Mapping[str, tuple[str, str]] | None = None,
) -> str:
    """The page of a run: ``report`` (``report.json``), ``config`` (``config.json``), ``run_dir``
    for the title; its task's ``words``, ``tool`` (Fig. 4 shows its angle) and critical
    ``phase``; links from ``report["artifacts"]``, relative to the
    run directory. ``outdated``: the stages whose files no longer follow from the run, by name:
    their files in words and why; the page says so at its top, with the command that makes them
    again."""
    artifacts, replay = report.get("artifacts", {}), report.get("replay", {})
    verdict = f" — {_yes_no(replay['success'], *map(escape, words.verbs))}" if replay else ""
    body = [
        f"<h1>imitate run{verdict}</h1>",
        f"<p class=sub><code>{escape(run_dir)}</code> · seed {report.get('seed', '?')}</p>",
        *(_outdated(outdated or {}, run_dir)),
        f"<p>{CLAIM}</p>",
        "<div class=row>" + _section("Headline", _table(_headline(report, words, phase)))
        + _section("Stage timings", _timings(report.get("timings", {}))) + "</div>",
    ]
    if "video" in artifacts:
        caption = VIDEO_CAPTION.format(noun=words.noun)
        body.append(_section("Video", _media("video", artifacts["video"], caption)))
    if "optimization" in report:
        body.append(_section("Collision-weight sweep", _sweep(report["optimization"])))
    figures = sorted(
        ((name, path) for name, path in artifacts.items() if path.startswith("figures/")),
        key=lambda item: LEADING_FIGURES.index(item[0]) if item[0] in LEADING_FIGURES
        else len(LEADING_FIGURES),  # stable: the others keep their order
    )
    if figures:
        body.append(_section("Figures", "".join(
            _media("img", path, CAPTIONS.get(name, name).format(tool=tool))
            for name, path in figures
        )))
    settings = _table((escape(k), _value(v)) for k, v in config.items())
    body += [
        _section("All numbers", _all_numbers(report)),
        _section("Settings (config.json)", settings),
        _section("Artifacts", _links(artifacts.values())),
    ]
    return _page(f"imitate run {run_dir}", body)


def eval_page(
    summary: dict, failures: list[str], links: list[str], title: str, score: str
) -> str:
    """The page of an evaluation: ``summary`` (``summary.json``), the failure videos and the
    other files to link, paths relative to the page; ``title`` names what was evaluated;
    ``score`` the name of the task's score (``Task.score.name``), whose numbers the summary
    holds as ``<score>_mean`` and ``<score>_min``, and its margin section as
    ``<score>_threshold`` and ``low_<score>``."""
    n, outcomes, run = summary["variations"], summary["outcomes"], summary["run"]
    low, high = summary["success_wilson95"]
    gap, seconds = summary["clearance_gap_mm"], summary["seconds_per_variation"]
    kept = summary["kept_margin"]
    where = f" on {run['workers']} workers" if run["workers"] else ""
    headline = [
        ("success", f"{outcomes['success']} of {n} = {summary['success_rate']:.3f}"),
        ("95 % Wilson interval", f"{low:.3f} … {high:.3f}"),
        (f"{score} over the replays",
         f"mean {summary[f'{score}_mean']:.3f}, min {summary[f'{score}_min']:.3f}"),
        ("plan − physics clearance [mm]",
         (", ".join(f"{k} {v:.2f}" for k, v in gap.items() if k != "plans") or "—")
         + f" over the {gap['plans']} plans that keep clear"),
        (f"plans that keep the {kept['margin_m'] * 1000:g} mm margin",
         f"{kept['plans']}: touching in physics {kept['physics_contact']}, "
         f"{score} below {kept[f'{score}_threshold']:g} in a replay {kept[f'low_{score}']}"),
        ("plans with the null-space push",
         f"{summary['nullspace_push']['plans']}: successes {summary['nullspace_push']['success']}"),
        ("seconds per variation", ", ".join(f"{k} {v:.1f}" for k, v in seconds.items())),
        ("this evaluation",
         f"{run['ran']} run now, {run['backend']}{where}, {run['wall_seconds']:.1f} s"),
    ]
    places = summary["outcomes_by_obstacle"]
    header = ("outcome", *(f"obstacle: {p.replace('_', ' ')}" for p in places), "all")
    rows = [
        (escape(o.replace("_", " ")), *(_n(places[p][o]) for p in places), _n(count))
        for o, count in outcomes.items()
    ]
    body = [
        f"<h1>imitate eval — {outcomes['success']} of {n} succeed</h1>",
        f"<p class=sub><code>{escape(title)}</code> · seed {summary['seed']} · suite digest "
        f"<code>{escape(summary['suite_digest'])}</code></p>",
        _section("Headline", _table((escape(k), escape(v)) for k, v in headline)),
        _section("Outcomes by obstacle placement", _table(rows, header)
                 + _media("img", "outcomes.png", OUTCOMES_CAPTION)),
    ]
    if failures:
        body.append(_section("Failure videos", "<div class=grid>" + "".join(
            _media("video", path, _failure(path)) for path in failures
        ) + "</div>"))
    body += [
        _section("Suite", _table(_suite_rows(summary["suite"], n))),
        _section("Files", _links(links + failures)),
    ]
    return _page(f"imitate eval {title}", body)


def save_run_page(
    run_dir: Path, report: dict, config: dict, words: Words, tool: str, phase: str,
    outdated: Mapping[str, tuple[str, str]] | None = None,
) -> Path:
    """Write ``run_dir/report.html`` from the run's report, settings and task's words, tool and
    phase (and the stages
    whose files are ``outdated``, see :func:`run_page`), atomically (inside
    :func:`imitate.rundir.artifacts.staged`: with the stage's commit)."""
    page = run_page(report, config, str(run_dir), words, tool, phase, outdated)
    return write_atomic(Path(run_dir) / PAGE, lambda tmp: tmp.write_text(page))


def save_eval_page(out: Path, summary: dict, score: str) -> Path:
    """Write ``out/report.html`` (``out``: an evaluation's folder) from its summary and the name
    of the task's score (see :func:`eval_page`), linking what is there: the failure videos of
    its digest, its files, the run's page."""
    out = Path(out)
    digests = [t["digest"] for t in summary.get("teachers", ())] or [summary["suite_digest"]]
    failures = sorted(
        p.relative_to(out).as_posix()
        for digest in digests for p in (out / "failures" / digest).glob("*.mp4")
    )
    files = ("summary.json", "results.jsonl", "outcomes.png", f"../{PAGE}")
    links = [name for name in files if (out / name).is_file()]
    page = eval_page(summary, failures, links, str(out), score)
    return write_atomic(out / PAGE, lambda tmp: tmp.write_text(page))


# --- Sections ----------------------------------------------------------------------------------


def _outdated(outdated: Mapping[str, tuple[str, str]], run_dir: str) -> list[str]:
    """A warning per stage whose files no longer follow from the run, with its command."""
    return [
        f"<p class=bad>Out of date: {escape(files)} ({escape(why)}); <code>imitate "
        f"{escape(stage)} {escape(run_dir)}</code> makes it again.</p>"
        for stage, (files, why) in outdated.items()
    ]


def _headline(report: dict, words: Words, phase: str) -> list[tuple[str, str]]:
    """(label, value HTML) of the key numbers present in ``report``, the task's from its
    ``words`` and its critical ``phase``."""
    demos, perception = report.get("demos", {}), report.get("perception", {})
    learning, opt, replay = (report.get(k, {}) for k in ("learning", "optimization", "replay"))
    rows = []
    if replay:
        rows += [
            ("success", _yes_no(replay["success"], "yes", "no")),
            *((escape(label), escape(text)) for label, text in words.headline(replay)),
            ("min distance, physics", _mm(replay["min_distance_m"])),
        ]
    if opt:
        pair = " / ".join(map(str, opt["closest_pair"])) or "none within 0.2 m"
        rows += [
            ("min distance, plan", f"{_mm(opt['min_distance_m'])} ({escape(pair)})"),
            (f"{escape(phase)} phase error",
             f"{shown(opt[error_keys(phase)[0]], '.1f', 1e3)} mm, "
             f"{shown(opt[error_keys(phase)[1]], '.2f')}°"),
        ]
        rows.append(("optimizer", "converged" if opt["converged"] else (
            f"not converged: stopped at its limit of {opt['iterations']} iterations with the "
            "best plan found, whose cost could still fall a little; the plan is what the "
            "replay above tested (<code>--max-iter</code> raises the limit)"
        )))
    if learning:
        k, bic, fast, full = (escape(str(learning[name])) for name in (
            "n_components", "bic", "n_components_fast_bic", "n_components_full_bic"))
        rows.append(("K chosen", f"{k} ({bic} BIC; fast {fast}, full {full})"))
    if demos:
        found, expected = (escape(str(demos[name])) for name in ("detected", "expected"))
        rows.append(("demonstrations found", f"{found} of {expected}"))
    if perception:
        rows.append(("tracking error", f"{shown(perception['pos_err_mm_median'], '.1f')} mm "
                     f"median, {shown(perception['pos_err_mm_p95'], '.1f')} mm p95"))
    return rows


def _timings(timings: dict) -> str:
    rows = [(escape(stage), _n(seconds, ".1f")) for stage, seconds in timings.items()]
    rows.append(("<b>total</b>", _n(sum(v for v in timings.values() if v is not None), ".1f")))
    return _table(rows, ("stage", "seconds"))


SWEEP_NOTES = (
    "The setting <code>sweep</code> holds fractions of <code>collision_weight</code> "
    "({weight:g}); each row's weight is its fraction times it. The chosen weight is in bold.",
    "<b>min distance</b>: the smallest signed distance of the plan's kinematics between parts "
    "that must not touch (negative: the held objects pass into the body). Kinematics have no "
    "contacts, so a plan can pass through a part; in physics the contacts push back, so a plan "
    "that passes tens of millimetres into the body shows only a few millimetres of "
    "penetration in the replay (Fig. 8, and the headline's <i>min distance, physics</i>).",
    "<b>max deviation</b>: the largest distance of the plan's relative position from the "
    "weight-0 plan's. <b>change in high-variance steps</b>: the share of the squared change "
    "from the weight-0 plan that falls in the steps whose GMR position variance is above its "
    "median, which are half of the steps by definition: 50 % is no preference, 100 % is every "
    "change where the demonstrations varied.",
)


def _suite_rows(suite: dict, n: int) -> list[tuple[str, str]]:
    """The suite's keys and values, ``variations`` as the ``n`` that ran (``--n`` replaces the
    suite's count)."""
    return [
        (escape(k), f"{n} ran (--n; the suite's own {v})" if k == "variations" and v != n
         else _value(v))
        for k, v in suite.items()
    ]


def _sweep(opt: dict) -> str:
    """The Fig. 9 sweep, one row per collision weight (its fraction of the collision weight
    and the weight); the chosen one in bold; what the columns mean below."""
    chosen_weight = opt["collision_weight"]
    rows = [
        (_n(e["weight"] / chosen_weight if chosen_weight else 0.0, "g"), _n(e["weight"], "g"),
         _n(_mm(e["min_distance_m"])), _n(shown(e["max_deviation_m"], ".1f", 1e3)),
         _n(shown(e["change_high_variance_share"], ".0f", 100)))
        for e in opt["sweep"]
    ]
    header = ("sweep", "weight", "min distance, plan", "max deviation from weight 0 [mm]",
              "change in high-variance steps [%]")
    chosen = [e["weight"] == chosen_weight for e in opt["sweep"]]
    notes = "".join(f"<p>{note.format(weight=chosen_weight)}</p>" for note in SWEEP_NOTES)
    return _table(rows, header, chosen) + notes


def _all_numbers(report: dict) -> str:
    """Every section of ``report`` as a table of its plain values (lists of objects apart)."""
    return "<div class=row>" + "".join(
        f"<div><h3>{escape(name)}</h3>" + _table(
            (escape(k), _value(v)) for k, v in section.items()
            if not (isinstance(v, list) and v and isinstance(v[0], dict))
        ) + "</div>"
        for name, section in report.items()
        if name not in SHOWN_APART and isinstance(section, dict)
    ) + "</div>"


# --- HTML --------------------------------------------------------------------------------------


def _page(title: str, body: list[str]) -> str:
    return (
        "<!DOCTYPE html>\n<html lang=en><head><meta charset=utf-8>"
        "<meta name=viewport content='width=device-width, initial-scale=1'>"
        f"<title>{escape(title)}</title><style>{STYLE}</style></head>\n<body>\n"
        + "\n".join(body) + "\n</body></html>\n"
    )


def _section(heading: str, content: str) -> str:
    return f"<section><h2>{escape(heading)}</h2>{content}</section>"


def _table(rows, header: tuple[str, ...] = (), bold: Sequence[bool] = ()) -> str:
    """Rows of cell HTML (a cell that starts with ``<td`` keeps its own tag); the rows marked
    in ``bold`` in bold."""
    lines = ["<tr>" + "".join(f"<th>{escape(h)}</th>" for h in header) + "</tr>"] if header else []
    for i, row in enumerate(rows):
        cells = "".join(c if c.startswith("<td") else f"<td>{c}</td>" for c in row)
        lines.append(f"<tr class=chosen>{cells}</tr>" if i < len(bold) and bold[i]
                     else f"<tr>{cells}</tr>")
    return f"<table>{''.join(lines)}</table>"


def _media(tag: str, src: str, caption: str) -> str:
    """An ``img`` or a ``video`` of ``src`` with a caption that links the file."""
    element = (
        f"<img src='{escape(src)}' alt='{escape(caption)}'>" if tag == "img"
        else f"<video controls preload=metadata src='{escape(src)}'></video>"
    )
    return (f"<figure>{element}<figcaption><a href='{escape(src)}'>{escape(src)}</a>: "
            f"{escape(caption)}</figcaption></figure>")


def _failure(path: str) -> str:
    """A failure video's caption from its name ``<id>-<outcome>.mp4``: ``variation 7: spill``."""
    number, outcome = Path(path).stem.split("-", 1)
    return f"variation {int(number)}: {outcome.replace('_', ' ')}"


def _links(paths) -> str:
    items = "".join(f"<li><a href='{escape(p)}'>{escape(p)}</a></li>" for p in paths)
    return f"<ul class=files>{items}</ul>"


def _n(value: float | str | None, spec: str = "") -> str:
    """A number (or its HTML) right-aligned in its own cell; "—" for ``None``."""
    return f"<td class=n>{'—' if value is None else format(value, spec)}</td>"


def shown(value: float | None, spec: str, scale: float = 1.0) -> str:
    """``value * scale`` formatted by ``spec`` for the page (a task's headline too); "—" where
    it was not measured (a report's ``null``)."""
    return "—" if value is None else format(scale * value, spec)


def _mm(metres: float | None) -> str:
    """A distance [m] in mm, red where negative (penetrating); "—" for ``None``."""
    text = f"{shown(metres, '.1f', 1e3)} mm"
    return f"<span class=bad>{text}</span>" if metres is not None and metres < 0 else text


def _yes_no(flag: bool, yes: str, no: str) -> str:
    return f"<span class=ok>{yes}</span>" if flag else f"<span class=bad>{no}</span>"


def _value(value) -> str:
    """A report or settings value as escaped text: floats to 4 significant digits."""
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, (list, tuple)) and all(isinstance(v, (str, int, float)) for v in value):
        text = ", ".join(f"{v:.4g}" if isinstance(v, float) else str(v) for v in value)
        return escape(text) or "—"
    if isinstance(value, (dict, list, tuple)):
        return f"<code>{escape(json.dumps(value))}</code>"
    return "—" if value is None else escape(str(value))
