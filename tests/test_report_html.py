"""``report.html``: the page of a run (written by every stage) and of an evaluation; every file it
references exists beside it, the key numbers are on it, and a partial run still has a page."""

import json
from html.parser import HTMLParser
from pathlib import Path

import pytest

from imitate.envs.task import get_task
from imitate.evaluation.report import summarize
from imitate.rundir import layout
from imitate.rundir.page import CAPTIONS, save_eval_page, save_run_page
from imitate.rundir.schema import REPORT_SCHEMA, check_values
from imitate.stages.config import RunConfig
from imitate.stages.runner import run_keys

POUR = get_task("pour")
WORDS = (POUR.words, POUR.objects[0], POUR.phase)  # what a run page takes of its task


class References(HTMLParser):
    """The ``src`` and ``href`` values of a page, and its text."""

    def __init__(self, page: str):
        super().__init__()
        self.paths: list[str] = []
        self.text: list[str] = []
        self.feed(page)

    def handle_starttag(self, tag, attrs):
        self.paths += [value for name, value in attrs if name in ("src", "href")]

    def handle_data(self, data):
        self.text.append(data)


def references(page: Path) -> References:
    """The references of ``page``, each checked to be a relative path to an existing file."""
    found = References(page.read_text())
    for path in found.paths:
        assert "://" not in path and not path.startswith("/"), path
        assert (page.parent / path).is_file(), path
    return found


def test_run_page_links_every_artifact_and_shows_the_key_numbers(quick_run):
    found = references(quick_run / layout.PAGE)
    report = json.loads((quick_run / layout.REPORT).read_text())
    assert set(report["artifacts"].values()) <= set(found.paths)
    assert {f"figures/{name}.png" for name in layout.FIGURES} <= set(found.paths)
    assert "video.mp4" in found.paths
    text = " ".join(found.text)
    opt, replay = report["optimization"], report["replay"]
    for number in (
        f"{1e3 * opt['min_distance_m']:.1f} mm", f"{1e3 * replay['min_distance_m']:.1f} mm",
        f"{replay['pour_fraction']:.2f}", f"{1e3 * opt['pour_phase_err_m']:.1f} mm",
        f"{report['learning']['n_components']} (", f"{report['timings']['figures']:.1f}",
        *(f"{entry['weight']:g}" for entry in opt["sweep"]),
    ):
        assert number in text, number
    assert ("pours" if replay["success"] else "does not pour") in text
    assert "GMM over time on the bottle's angle" in text and "reproduces the pour" in text


def test_partial_run_has_a_page_of_what_exists(tmp_path):
    report = {
        "schema": REPORT_SCHEMA, "seed": 4,
        "demos": {"detected": 5, "expected": 5, "boundary_err_s_max": 0.07},
        "perception": {"pos_err_mm_median": 4.2, "pos_err_mm_p95": 11.9},
        "timings": {"observe": 15.4},
        "artifacts": {name: name for name in ("config.json", "observations.npz", "demos.npz")},
    }
    for name in report["artifacts"].values():
        (tmp_path / name).write_text("")
    found = references(save_run_page(tmp_path, report, RunConfig.quick().to_json(), *WORDS))
    text = " ".join(found.text)
    assert "5 of 5" in text and "4.2 mm median" in text and "seed 4" in text
    assert not any(path.endswith((".png", ".mp4")) for path in found.paths)
    assert "Collision-weight sweep" not in text and "success" not in text


def _nulled(node, kinds: set[str]):
    """``node`` with every float null but those of the keys ``kinds``."""
    if isinstance(node, dict):
        return {k: v if k in kinds else _nulled(v, kinds) for k, v in node.items()}
    if isinstance(node, list):
        return [_nulled(v, kinds) for v in node]
    return None if isinstance(node, float) else node


def test_numbers_not_measured_show_as_a_dash(quick_run, tmp_path):
    """A report's numbers may be null (not measured, as its schema allows): the page shows
    "—" for each; a closest pair of numbers shows as it is."""
    report = json.loads((quick_run / layout.REPORT).read_text())
    report = _nulled(report, {"collision_weight", "sigma_max_scale", "weight"})
    report["optimization"]["closest_pair"] = [1, 2]
    check_values(report, quick_run / layout.REPORT, *run_keys(POUR))  # as a stage reads it
    page = save_run_page(tmp_path, report, RunConfig.quick().to_json(), *WORDS)
    text = " ".join(References(page.read_text()).text)
    assert "— mm median, — mm p95" in text and "(1 / 2)" in text and "— mm, —°" in text
    assert "— (mean —, min — over the replays)" in text


@pytest.mark.parametrize("task", ["pour", "insert"])
def test_a_task_headline_shows_a_dash_where_not_measured(task):
    task = get_task(task)
    keys = [key.partition(".")[2] for key in task.keys if key.startswith("replay.")]
    ((label, text),) = task.words.headline(dict.fromkeys(keys))
    assert "None" not in text and text.count("—") >= 3


def test_strings_of_a_crafted_report_are_escaped(tmp_path):
    script = "<script>alert('demos')</script>"
    report = {
        "schema": REPORT_SCHEMA, "seed": 4, "demos": {"detected": script, "expected": 5},
        "learning": {"n_components": "<img src=x onerror=alert(1)>", "bic": "full",
                     "n_components_fast_bic": 3, "n_components_full_bic": 4},
    }
    page = (save_run_page(tmp_path, report, RunConfig.quick().to_json(), *WORDS)).read_text()
    assert "<script>" not in page and "<img src=x" not in page
    assert "&lt;script&gt;" in page and "&lt;img src=x" in page


def test_eval_page_links_its_files_and_failure_videos(tmp_path):
    out, digest = tmp_path / "eval", "0123456789abcdef"
    records = [
        {"outcome": outcome, "seconds": 2.0, "plan": {"min_distance_m": 0.01},
         "clearance_gap_m": 0.001, "pour_mean": pour, "pour_min": pour,
         "settings": {"obstacle": None, "in_path": False}}
        for outcome, pour in (("success", 1.0), ("success", 0.95), ("spill", 0.5))
    ]
    summary = {
        "suite_digest": digest, "seed": 0, "suite": {"variations": 3, "shapes": ["box"]},
        "path_points": 10, **summarize(records, POUR),
        "run": {"ran": 3, "wall_seconds": 6.0, "backend": "local", "workers": 2},
    }
    video = f"failures/{digest}/0002-spill.mp4"
    (out / "failures" / digest).mkdir(parents=True)
    for name in ("summary.json", "results.jsonl", "outcomes.png", video):
        (out / name).write_text("")
    found = references(save_eval_page(out, summary, POUR.score.name))
    assert video in found.paths and "outcomes.png" in found.paths
    assert "../report.html" not in found.paths  # the run has no page
    text = " ".join(found.text)
    low, high = summary["success_wilson95"]
    assert "2 of 3 = 0.667" in text and f"{low:.3f} … {high:.3f}" in text
    assert "variation 2: spill" in text


def test_every_figure_has_a_caption():
    assert set(CAPTIONS) == set(layout.FIGURES)


def test_run_page_explains_its_numbers(quick_run):
    from imitate.rundir.page import run_page

    report = json.loads((quick_run / layout.REPORT).read_text())
    config = json.loads((quick_run / "config.json").read_text())
    opt = report["optimization"]
    page = run_page(report, config, str(quick_run), *WORDS)
    text = " ".join("".join(References(page).text).split())
    assert "fractions of collision_weight" in text
    for entry, fraction in zip(opt["sweep"], config["sweep"], strict=True):
        assert f"{fraction:g}" in text and f"{entry['weight']:g}" in text
    assert "contacts push back" in text and "half of the steps by definition" in text
    done = "converged" if opt["converged"] else "not converged: stopped at its limit"
    assert done in text
    assert "may leave the ±2σ band" in CAPTIONS["fig9_collision_sweep"]


def test_eval_page_says_how_many_variations_ran(tmp_path):
    records = [{"outcome": "success", "seconds": 2.0, "plan": {"min_distance_m": 0.01},
                "clearance_gap_m": 0.001, "pour_mean": 1.0, "pour_min": 1.0,
                "settings": {"obstacle": None, "in_path": False}}] * 6
    summary = {
        "suite_digest": "0123456789abcdef", "seed": 0, "suite": {"variations": 100},
        "path_points": 10, **summarize(records, POUR),
        "run": {"ran": 6, "wall_seconds": 6.0, "backend": "local", "workers": 2},
    }
    text = " ".join(References(save_eval_page(tmp_path, summary, POUR.score.name).read_text()).text)
    assert "6 ran (--n; the suite's own 100)" in text
