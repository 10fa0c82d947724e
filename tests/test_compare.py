"""Teachers as a dimension of an evaluation (learned once, reused on resume) and the paired
comparison of similarity weightings (the same variations for every weighting)."""

import json
from pathlib import Path

import numpy as np
import pytest

from imitate.cli import main
from imitate.demos.oracle import oracle_model
from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.evaluation import Suite, evaluate, named_suite, sensitivity
from imitate.evaluation.compare import compare, dose, paired, parse_sweep, settings_digest
from imitate.evaluation.compare_report import BUDGET, markdown, plot_comparison
from imitate.evaluation.inference import crossing, ed50, teacher_effect
from imitate.evaluation.report import wilson
from imitate.evaluation.suite_run import RESULTS, default_out, last_records
from imitate.evaluation.teachers import teachers
from imitate.learning import LearningConfig
from imitate.motion import SIMILARITIES
from imitate.motion.replay import planning_task
from imitate.rundir.artifacts import save_json, save_npz
from imitate.stages import provenance, runner
from imitate.stages.config import RunConfig, load_config

POUR = get_task("pour")
TINY = {"max_iter": 3, "replays": 1, "particles": [4, 6], "obstacle_share": 0.5}


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory) -> Path:
    """A run of teacher seed 0 observed and learned at the quick settings, two demonstrations."""
    run_dir = tmp_path_factory.mktemp("run")
    config = RunConfig.quick(n_demos=2)
    for stage in ("observe", "learn"):
        runner.run_stage(stage, run_dir, config)
    return run_dir


@pytest.fixture(scope="module")
def model_dir(tmp_path_factory) -> Path:
    """A folder holding an oracle model alone (no run settings)."""
    folder = tmp_path_factory.mktemp("model")
    gaze = planning_task().gaze
    learned = oracle_model(gaze, learning=LearningConfig(k_max=6), rate=20.0)
    save_npz(folder / "model.npz", {**learned.to_arrays(), "gaze": gaze})
    return folder


def test_teachers_are_learned_once_and_reused_on_resume(quick_run, monkeypatch):
    out = quick_run / "eval"
    first = teachers(quick_run, out, 2)
    folder = out / "teachers" / "seed-1"
    assert [t.seed for t in first] == [0, 1]
    assert first[0].path == quick_run / "model.npz" and first[1].path == folder / "model.npz"
    assert load_config(folder) == RunConfig.quick(n_demos=2, seed=1)
    assert first[0].model_bytes != first[1].model_bytes  # another teacher, another model

    def learn_again(*args, **kwargs):
        raise AssertionError("a teacher was observed and learned again")

    with monkeypatch.context() as patched:
        patched.setattr(runner, "run_stage", learn_again)
        again = teachers(quick_run, out, 2)
    assert [t.model_bytes for t in again] == [t.model_bytes for t in first]
    assert again[1].default_run["pour_fractions"]  # the teacher's default scene, replayed
    ran = []
    with monkeypatch.context() as patched:  # other code: the teacher is learned again
        patched.setattr(provenance, "code_digest", lambda: "other code")
        patched.setattr(runner, "run_stage", lambda stage, *args, **kw: ran.append(stage))
        teachers(quick_run, out, 2)
    assert ran == ["observe", "learn", "optimize", "replay"]
    (folder / "model.npz").write_bytes(b"not the model learn wrote")
    relearned = teachers(quick_run, out, 2)  # its provenance fails: learned again, the same
    assert relearned[1].model_bytes == first[1].model_bytes


def test_teachers_learned_in_processes_are_those_learned_one_by_one(quick_run, tmp_path,
                                                                      monkeypatch):
    together = teachers(quick_run, tmp_path / "together", 3, workers=2)
    alone = teachers(quick_run, tmp_path / "alone", 2)
    assert [t.seed for t in together] == [0, 1, 2]
    assert together[1].model_bytes == alone[1].model_bytes  # the same teacher, the same model
    monkeypatch.setattr(runner, "run_stage", lambda *a, **k: pytest.fail("learned again"))
    again = teachers(quick_run, tmp_path / "together", 3, workers=2)
    assert [t.model_bytes for t in again] == [t.model_bytes for t in together]


def test_eval_reports_each_teacher_and_resumes_without_learning(quick_run, monkeypatch):
    suite = Suite.from_dict(TINY)
    summary = evaluate(quick_run, suite, n=2, n_teachers=2, workers=2, videos=0)
    assert [t["seed"] for t in summary["teachers"]] == [0, 1]
    assert summary["variations"] == 4 and all(t["variations"] == 2 for t in summary["teachers"])
    assert sum(t["success"] for t in summary["teachers"]) == summary["outcomes"]["success"]
    records = last_records(default_out(quick_run, "default", suite))
    assert [(r["teacher"], r["id"]) for r in records] == [(0, 0), (0, 1), (1, 0), (1, 1)]
    assert len({r["digest"] for r in records}) == 2  # one per teacher's model
    monkeypatch.setattr(runner, "run_stage", lambda *a, **k: pytest.fail("learned again"))
    again = evaluate(quick_run, suite, n=2, n_teachers=2, workers=1, videos=0)
    assert again["run"]["ran"] == 0 and again["suite_digest"] == summary["suite_digest"]


def test_compare_plans_the_same_variations_for_every_weighting(model_dir):
    result = compare(model_dir, Suite.from_dict(TINY), ["variance", "inverted"], name="tiny",
                     n=2, n_teachers=1, workers=2)
    out = model_dir / "compare" / "tiny"
    records = [json.loads(line) for line in (out / RESULTS).read_text().splitlines()]
    by = {s: sorted((r for r in records if r["settings"]["similarity"] == s),
                    key=lambda r: r["id"]) for s in ("variance", "inverted")}
    assert [settings_digest(r) for r in by["variance"]] == [settings_digest(r) for r in
                                                            by["inverted"]]
    assert len({r["digest"] for r in records}) == 2  # each weighting its own records
    assert set(result["weightings"]) == {"variance", "inverted"}
    (pair,) = result["pairs"]
    within = pair["within_models"]
    assert within["both"] + within["only_a"] + within["only_b"] + within["neither"] == 2
    assert 0 <= within["mcnemar_p"] <= 1
    effect = pair["teacher_level"]["pour_min"]  # one teacher: a mean, no interval
    assert effect["teachers"] == 1 and effect["ci95"] is None
    assert all(r["mahalanobis"]["rms"] >= 0 for r in records)
    assert json.loads((out / "compare.json").read_text())["pairs"] == result["pairs"]
    assert "| variance vs inverted |" in (out / "compare.md").read_text()
    assert "Within these models" in (out / "compare.md").read_text()
    assert ("Total weight (variance: eq. 21's; inverted: eq. 21's per dimension)."
            in (out / "compare.md").read_text())
    assert set(BUDGET) == set(SIMILARITIES)  # every weighting says what its total matches
    assert (out / "compare.png").stat().st_size > 0
    again = compare(model_dir, Suite.from_dict(TINY), ["variance", "inverted"], name="tiny",
                    n=2, n_teachers=1, workers=1)
    assert again["run"]["ran"] == 0  # resumed: nothing to run
    shuffled = {**by, "inverted": by["inverted"][::-1]}
    with pytest.raises(ImitateError, match="not of the same variations"):
        paired(shuffled, POUR)


def test_compare_reports_the_primary_endpoint_in_each_block_of_teachers(quick_run):
    result = compare(quick_run, Suite.from_dict(TINY), ["uniform", "variance"], name="blocks",
                     n=2, n_teachers=1, workers=2, confirm=1, primary="variance-uniform")
    assert result["teachers"] == [0, 1000]  # the confirmation teacher learned beside the run's
    replication = result["replication"]
    assert (replication["a"], replication["b"]) == ("variance", "uniform")
    assert replication["development"]["teachers"] == [0]
    assert replication["confirmation"]["teachers"] == [1000]
    assert replication["all"]["effect"]["teachers"] == 2
    assert replication["verdict"] in ("no development verdict", "replicated", "not replicated",
                                      "reversed")
    text = (quick_run / "compare" / "blocks" / "compare.md").read_text()
    assert "Primary endpoint, declared before the runs: **variance - uniform" in text
    assert "| confirmation (1) | 1000 |" in text
    with pytest.raises(ImitateError, match="--confirm with --sweep not accepted"):
        compare(quick_run, Suite.from_dict(TINY), ["uniform", "variance"], confirm=1,
                sweep=("path_length_weight", (1.0, 2.0)))
    with pytest.raises(ImitateError, match="--primary 'variance-precision' not accepted"):
        compare(quick_run, Suite.from_dict(TINY), ["uniform", "variance"],
                primary="variance-precision")


def test_the_importance_weighting_plans_with_the_teachers_measured_tolerance(model_dir):
    with pytest.raises(ImitateError, match="needs teacher 0's measured tolerance"):
        compare(model_dir, Suite.from_dict(TINY), ["variance", "importance"], name="importance",
                n=1, n_teachers=1, workers=1)
    path = sensitivity.result_path(model_dir, 0)
    path.parent.mkdir()
    save_json(path, {"model": sensitivity.model_digest((model_dir / "model.npz").read_bytes()),
                     "magnitudes": [1, 2, 4], "quadratic_form": np.eye(7).tolist()})
    result = compare(model_dir, Suite.from_dict(TINY), ["variance", "importance"],
                     name="importance", n=1, n_teachers=1, workers=1)
    assert result["weightings"]["importance"]["variations"] == 1
    summary = evaluate(model_dir, Suite.from_dict({**TINY, "similarity": "importance"}), n=1,
                       workers=1, videos=0)
    assert summary["variations"] == 1


def test_compare_appends_through_no_hard_link(model_dir, tmp_path):
    """Review F: a results.jsonl that is another name of a user's file is refused, the file
    untouched."""
    notes = tmp_path / "notes.txt"
    notes.write_text("mine\n")
    out = model_dir / "compare" / "linked"
    out.mkdir(parents=True)
    (out / RESULTS).hardlink_to(notes)
    with pytest.raises(ImitateError, match="is a hard link; imitate appends to none"):
        compare(model_dir, Suite.from_dict(TINY), ["variance", "inverted"], name="linked", n=1,
                n_teachers=1, workers=1)
    assert notes.read_text() == "mine\n"


def test_shipped_suites_load_and_a_bad_name_is_refused_in_one_line(capsys, model_dir):
    name, suite = named_suite("effort", POUR)
    assert name == "effort" and suite["path_length_weight"][0] > 1 and suite["obstacle_share"] == 0
    assert named_suite(None, POUR) == ("default", Suite.default())
    with pytest.raises(ImitateError, match="--suite nope not accepted: one of default, .*effort"):
        named_suite("nope", POUR)
    assert main(["compare", str(model_dir), "--similarity", "variance,flat"]) == 1
    # the last line: what the library logged before main() set up logging comes first
    err = capsys.readouterr().err.strip().splitlines()[-1]
    assert err.startswith("imitate compare: error: --similarity variance,flat not accepted")
    assert main(["eval", str(model_dir), "--teachers", "0"]) == 1
    assert "--teachers 0 not accepted" in capsys.readouterr().err


def _records(weighting: str, teachers: dict[int, list[bool]], pour: float = 0.95) -> list[dict]:
    """Synthetic records: per teacher, its variations' successes."""
    return [
        {"teacher": t, "id": i, "outcome": "success" if ok else "spill",
         "settings": {"similarity": weighting, "id": i}, "pour_min": pour if ok else 0.5,
         "mahalanobis": {"rms": 1.0 + (weighting == "uniform")},
         "plan": {"min_distance_m": 0.012, "pour_phase_err_m": 0.003, "nullspace_push": i == 0},
         "change": {"pour_m": 0.01, "pour_deg": 1.0, "low_variance_m": 0.02}}
        for t, outcomes in teachers.items() for i, ok in enumerate(outcomes)
    ]


@pytest.mark.parametrize("n", [6, 40, 100, 180, 300])
def test_a_weighting_that_always_succeeds_is_plotted_with_a_zero_error_bar(n):
    """Wilson's bounds at n of n and 0 of n are exact (rounding once gave 1 - 1e-16, a
    negative error bar and a traceback instead of compare.png)."""
    assert wilson(n, n)[1] == 1.0 and wilson(0, n)[0] == 0.0
    result = {"suite_name": "s", "suite": {}, "seed": 0, "teachers": [0, 1],
              "variations_per_teacher": n,
              **paired({"variance": _records("variance", {0: [True] * n, 1: [True] * n}),
                        "uniform": _records("uniform", {0: [False] * n, 1: [True] * n})}, POUR)}
    plot_comparison(result, POUR)  # no negative yerr
    assert f"| variance | 100 % | {n}/{n}, {n}/{n} | {2 * n}/{2 * n} (" in markdown(result, POUR)
    assert "push changed (the attractors alone kept less than the margin): variance 2/" in \
        markdown(result, POUR)


def test_the_teacher_level_interval_finds_a_known_effect_and_no_effect():
    """Ten teachers whose success differs by a known 20 points, with noise: the interval covers
    it and excludes 0; with no difference, it covers 0 and the test does not reject."""
    rng = np.random.default_rng(0)
    base = rng.uniform(0.3, 0.7, 10)
    effect = teacher_effect(0.2 + rng.normal(0, 0.05, 10))
    low, high = effect["ci95"]
    assert low <= 0.2 <= high and low > 0 and effect["p"] < 0.01 and effect["a_higher"] == 10
    null = teacher_effect(rng.normal(0, 0.05, 10))
    assert null["ci95"][0] < 0 < null["ci95"][1] and null["p"] > 0.05
    # from records: a teacher with 40 variations is one observation, not 40
    n = 40
    a = {t: list(rng.random(n) < p + 0.2) for t, p in enumerate(base)}
    b = {t: list(rng.random(n) < p) for t, p in enumerate(base)}
    (pair,) = paired({"variance": _records("variance", a),
                      "uniform": _records("uniform", b)}, POUR)["pairs"]
    success = pair["teacher_level"]["success_rate"]
    assert success["teachers"] == 10 and success["ci95"][0] > 0
    assert pair["teacher_level"]["mahalanobis_rms"]["mean"] == -1.0


def test_ed50_is_where_the_mean_curve_crosses_half_with_an_interval_over_teachers():
    levels = np.array([10.0, 20, 40, 80, 160])
    falling = np.array([[1.0, 0.9, 0.6, 0.4, 0.0]] * 4)  # crosses at 40..80, 60 % to 40 %
    found = ed50(levels, falling, rising=False)
    assert found["ed50"] == pytest.approx(np.sqrt(40 * 80))  # halfway in log
    assert found["ci95"] == [pytest.approx(found["ed50"])] * 2
    # past 50 % everywhere: below the sweep; short of it at the end: beyond it
    assert crossing(levels, np.full(5, 0.8), rising=False) == np.inf
    assert crossing(levels, np.full(5, 0.8), rising=True) == -np.inf
    assert crossing(levels, np.full(5, 0.2), rising=False) == -np.inf
    # the last crossing in the curve's direction: a dip below 50 % and back is not it
    assert crossing(levels, np.array([0.6, 0.4, 0.8, 0.9, 0.9]), rising=True) == pytest.approx(
        20 * 2**0.25)
    assert np.isnan(crossing(levels, np.full(5, 0.8), rising=None))


def test_a_sweep_is_numeric_increasing_and_refused_in_one_line():
    assert parse_sweep("path_length_weight=10,20,40") == ("path_length_weight", (10, 20, 40))
    for bad in ("path_length_weight=40,20", "similarity=1,2", "nope=1,2", "collision_weight=1",
                "collision_weight=a,b", "path_length_weight=10,5000",
                "path_length_weight=" + ",".join(str(v) for v in range(1, 22))):
        with pytest.raises(ImitateError, match="not accepted"):
            parse_sweep(bad)


def test_a_weighting_that_never_clears_counts_as_twice_as_high_not_as_unknown():
    """Dose response: uniform's success stays 0 and its plans never keep the margin, so its
    ED50 and first clearing level lie beyond the sweep: counted as surely >= 2x eq. 21's."""
    def level(variance_rate: float, variance_clear: float) -> dict:
        by = {
            "variance": {"success_rate": variance_rate, "pour_min": 1.0,
                         "clearance_median_mm": variance_clear},
            "uniform": {"success_rate": 0.0, "pour_min": 0.5, "clearance_median_mm": -20.0},
        }
        return {"weightings": {
            s: {"by_teacher": {"0": t, "1": t}, "mahalanobis_rms_median": 1.0,
                "pour_error_median_mm": 2.0, "clearance_median_mm": t["clearance_median_mm"]}
            for s, t in by.items()
        }}

    found = dose([10.0, 100.0, 1000.0], [level(0.0, -5.0), level(1.0, 12.0), level(1.0, 14.0)],
                 POUR)
    assert found["rising"] is True
    variance, uniform = found["weightings"]["variance"], found["weightings"]["uniform"]
    assert variance["ed50"] == pytest.approx(np.sqrt(10 * 100)) and uniform["ed50"] == ">1000"
    assert variance["first_clear_by_teacher"] == {"0": 100.0, "1": 100.0}
    assert uniform["first_clear_by_teacher"] == {"0": ">1000", "1": ">1000"}
    (pair,) = found["pairs"]
    assert pair["ed50"] == {"b_twice_a": 2, "a_twice_b": 0, "untold": 0}
    assert pair["first_clear"] == {"b_twice_a": 2, "a_twice_b": 0, "untold": 0}
