"""``imitate eval``: the suite's checks, drawing variations, outcomes, and a tiny evaluation that
gives the same records on 1 and 2 local workers, after a resume, and on Ray."""

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from imitate.cli import main
from imitate.demos.oracle import oracle_model
from imitate.envs import tasks
from imitate.envs.pour.outcome import outcome
from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.evaluation import Suite, evaluate, load_suite, named_suite
from imitate.evaluation.report import summarize, teacher_table, text, wilson
from imitate.evaluation.suite import keys
from imitate.evaluation.suite_run import RESULTS, default_out, last_records, read_records
from imitate.evaluation.variation import Variation, draw
from imitate.learning import LearnedModel, LearningConfig
from imitate.models.scene import TABLE_HEIGHT
from imitate.motion.replay import planning_task
from imitate.rundir.artifacts import save_json, save_npz
from imitate.stages import provenance
from imitate.stages.files import Learned, ModelFile

POUR = get_task("pour")
# Three variations that run in seconds: few particles, a short optimization, two replays.
TINY = {
    "variations": 3, "max_iter": 3, "replays": 2, "particles": [4, 6], "obstacle_share": 1.0,
    "in_path_share": 0.5,
}


@pytest.fixture(scope="module")
def model_arrays():
    gaze = planning_task().gaze
    learned = oracle_model(gaze, learning=LearningConfig(k_max=6), rate=20.0)
    return {**learned.to_arrays(), "gaze": gaze}


def _run_dir(tmp_path: Path, arrays: dict) -> Path:
    save_npz(tmp_path / "model.npz", arrays)
    return tmp_path


def _out(run_dir: Path) -> Path:
    """Where an evaluation of the tiny suite goes by default."""
    return default_out(run_dir, "default", Suite.from_dict(TINY))


def _without_timings(records: list[dict]) -> list[dict]:
    out = []
    for record in sorted(records, key=lambda r: r["id"]):
        copy = json.loads(json.dumps(record))
        copy.pop("seconds")
        copy["plan"].pop("seconds")
        out.append(copy)
    return out


@pytest.mark.parametrize(
    "text, suffix, match",
    [
        ("replay = 1\n", ".toml", "unknown entry 'replay'"),
        ("particles = [50, 500]\n", ".toml", r"entry particles=\[50, 500\] not accepted"),
        ("bottle_grasp = [0.1, 0.06]\n", ".toml", "entry bottle_grasp="),
        ("replays = 1.5\n", ".toml", "entry replays=1.5 not accepted: a whole number"),
        ("obstacle_share = true\n", ".toml", "entry obstacle_share=True"),
        ('similarity = "flat"\n', ".toml", "entry similarity='flat' not accepted: one of"),
        ("similarity = 1\n", ".toml", "entry similarity=1 not accepted"),
        ('{"shapes": ["box", "sphere"]}', ".json", r"entry shapes=\['box', 'sphere'\]"),
        ('{"shapes": []}', ".json", "entry shapes="),
        ("", ".toml", "is empty"),
        ("", ".json", "is empty"),
        ("{", ".json", "not valid JSON"),
        ("replays =", ".toml", "not valid TOML"),
        ("replays: 1", ".yaml", "a .toml or .json file"),
    ],
)
def test_bad_suite_refused_in_one_line(tmp_path, text, suffix, match):
    path = tmp_path / f"suite{suffix}"
    path.write_text(text)
    with pytest.raises(ImitateError, match=match) as err:
        load_suite(path)
    assert "\n" not in str(err.value)


def test_suite_reads_toml_and_json_alike(tmp_path):
    (tmp_path / "a.toml").write_text('particles = 40\nshapes = ["box"]\nobstacle_x = [0.5, 0.6]\n')
    (tmp_path / "a.json").write_text(
        json.dumps({"particles": 40, "shapes": ["box"], "obstacle_x": [0.5, 0.6]})
    )
    a, b = load_suite(tmp_path / "a.toml"), load_suite(tmp_path / "a.json")
    assert a == b and a["particles"] == (40, 40) and a["shapes"] == ("box",)
    assert a.digest(0, 0, b"m", "c") == b.digest(0, 0, b"m", "c") != a.digest(1, 0, b"m", "c")
    assert a.digest(0, 0, b"m", "c") != a.digest(0, 0, b"n", "c") != a.digest(0, 0, b"n", "code")
    assert a.digest(0, 0, b"m", "c") != a.digest(0, 3, b"m", "c")  # the teacher's seed counts
    assert a.replace(variations=7).digest(0, 0, b"m", "c") == a.digest(0, 0, b"m", "c")  # n grows


@pytest.mark.parametrize(("stem", "name"), [("..", "__"), ("a$\\frac$b", "a__frac_b"),
                                            ("<i>x", "_i_x"), ("effort-2", "effort-2")])
def test_a_suite_files_name_is_safe_in_paths_pages_and_figures(tmp_path, stem, name):
    """Review E: the name names a folder under the run's, a Markdown heading and a figure's
    title: no folder above, no HTML, no mathtext."""
    path = tmp_path / f"{stem}.toml"
    path.write_text("particles = 40\n")
    assert named_suite(str(path), get_task("pour"))[0] == name


def test_eval_help_documents_every_suite_key(capsys):
    assert Suite.default()["variations"] >= 100
    with pytest.raises(SystemExit):
        main(["eval", "--help"])
    documented = set(re.findall(r"^  (\w+) \(.*\): \S", capsys.readouterr().out, re.MULTILINE))
    assert documented == {name for task in tasks.NAMES for name in keys(task)}


def test_variations_are_drawn_per_id_and_round_trip():
    suite = Suite.default().replace(in_path_share=1.0, obstacle_share=1.0)
    path = np.array([[0.44, 0.0, 0.68], [0.45, 0.02, 0.67]])
    first = [draw(suite, 3, i, path) for i in range(20)]
    assert first[7] == draw(suite, 3, 7, path) != draw(suite, 4, 7, path)
    for v in first:
        assert Variation.from_json(json.loads(json.dumps(v.to_json()))) == v
        assert v.in_path and len(v.replay_seeds) == suite["replays"]
        o = v.obstacle
        top = o.pos[2] + o.size[-1]
        assert o.pos[2] - o.size[-1] == pytest.approx(TABLE_HEIGHT)
        held = [
            p for p in path
            if top >= p[2] + suite["path_overlap"][0] - 1e-9
            and (np.all(np.abs(p[:2] - o.pos[:2]) <= o.size[:2]) if o.shape == "box"
                 else np.hypot(*(p[:2] - o.pos[:2])) <= o.size[0])
        ]
        assert held, f"obstacle {o} holds no path point"
    assert all(draw(suite, 3, i, np.empty((0, 3))).in_path is False for i in range(5))


def _record(**changes) -> dict:
    """A variation's record of digest ``d`` as results.jsonl holds it, with ``changes``."""
    settings = draw(Suite.default(), 0, 0, np.empty((0, 3))).to_json()
    replay = {"seed": 1, "pour_fraction": 0.5, "spilled": 3, "min_distance_m": 0.01}
    record = {
        "digest": "d", "teacher": 0, "id": 0, "settings": settings, "outcome": "spill",
        "pour_mean": 0.5, "pour_min": 0.5,
        "plan": {"min_distance_m": 0.02, "seconds": 0.1, "nullspace_push": False,
                 "pour_phase_err_m": 0.002, "pour_phase_err_deg": 0.5},
        "change": {"pour_m": 0.001, "pour_deg": 0.2, "low_variance_m": 0.003},
        "mahalanobis": {"rms": 1.0}, "replays": [replay], "physics_min_distance_m": 0.01,
        "clearance_gap_m": 0.01,
        "seconds": 1.0,
    }
    return json.loads(json.dumps({**record, **changes}))


def test_records_that_could_name_a_file_outside_are_skipped(tmp_path):
    good = _record()
    crafted = [
        {**good, "id": 1, "outcome": "x/../../../outside"}, {**good, "id": "2"},
        {**good, "id": -3}, {**good, "id": True}, {"digest": "d", "id": 4},
    ]
    path = tmp_path / RESULTS
    path.write_text("\n".join(json.dumps(r) for r in [good, *crafted]) + "\n")
    assert read_records(path, "d", POUR) == [good]


def test_a_line_not_utf8_or_a_record_lacking_what_the_summary_reads_is_skipped(tmp_path):
    """Review N-e8, N-e10, X7: tracebacks before."""
    good = _record()
    bad = [
        {k: v for k, v in good.items() if k != "seconds"}, _record(id=1, settings=None),
        _record(id=2, pour_min="abc"), _record(id=3, plan={}), _record(id=4, replays=[]),
        _record(id=5, settings={**good["settings"], "obstacle": {"shape": "box"}}),
        _record(id=6, teacher=None), _record(id=7, mahalanobis=None),
        _record(id=8, mahalanobis={"rms": None}),
        # what compare pairs (review X7)
        _record(id=9, change=None), _record(id=10, change={"pour_m": 0.001}),
        _record(id=11, plan={**good["plan"], "nullspace_push": "x"}),
        _record(id=12, plan={**good["plan"], "pour_phase_err_m": None}),
        _record(id=13, mahalanobis={"rms": "abc"}),
    ]
    path = tmp_path / RESULTS
    lines = [json.dumps(r).encode() for r in bad] + [b'{"digest": "d", "note": "caf\xe9"}']
    path.write_bytes(b"\n".join([*lines, json.dumps(good).encode()]) + b"\n")
    assert read_records(path, "d", POUR) == [good]
    assert summarize(read_records(path, "d", POUR), POUR)["variations"] == 1


def test_eval_holds_the_run_directory(tmp_path, model_arrays):
    from imitate.rundir.lock import locked

    run_dir = _run_dir(tmp_path, model_arrays)
    with locked(run_dir, "imitate learn"):
        with pytest.raises(ImitateError, match="is in use by .*imitate learn"):
            evaluate(run_dir, Suite.from_dict(TINY), workers=1, videos=0)
    assert not (run_dir / "eval").exists()


def test_a_suite_that_is_no_text_or_too_deep_is_refused_in_one_line(tmp_path):
    (tmp_path / "latin.toml").write_bytes("replays = 2 # \u00e9\n".encode("latin-1"))
    with pytest.raises(ImitateError, match="it is not UTF-8 text"):
        load_suite(tmp_path / "latin.toml")
    (tmp_path / "deep.json").write_text("[" * 200_000)
    with pytest.raises(ImitateError, match="is not valid JSON"):
        load_suite(tmp_path / "deep.json")


def test_evaluations_of_another_weight_or_weighting_keep_the_others(tmp_path, model_arrays):
    run_dir = _run_dir(tmp_path, model_arrays)
    suite = Suite.from_dict(TINY)
    control = suite.replace(collision_weight=0.0)
    summaries = [
        evaluate(run_dir, s, n=1, workers=1, videos=0)
        for s in (suite, control, suite.replace(similarity="uniform"))
    ]
    outs = [run_dir / "eval" / f for f in
            ("default-w10000-variance", "default-w0-variance", "default-w10000-uniform")]
    assert outs == [default_out(run_dir, "default", s) for s in
                    (suite, control, suite.replace(similarity="uniform"))]
    for out, summary in zip(outs, summaries, strict=True):
        assert json.loads((out / "summary.json").read_text()) == summary
        assert (out / "report.html").is_file()
        assert read_records(out / RESULTS, summary["suite_digest"], POUR)
    elsewhere = evaluate(run_dir, control, n=1, workers=1, videos=0, out=tmp_path / "control")
    assert elsewhere["suite_digest"] == summaries[1]["suite_digest"]
    assert (tmp_path / "control" / "report.html").is_file()


def test_wilson_interval():
    assert wilson(0, 10) == pytest.approx((0.0, 0.2775), abs=1e-4)
    assert wilson(5, 10) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    assert wilson(10, 10)[1] == 1.0


def _replay(pour, spilled=0, distance=0.01, diverged=False):
    return {"pour_fraction": pour, "spilled": spilled, "min_distance_m": distance,
            "diverged": diverged}


@pytest.mark.parametrize(
    "plan, replays, expected",
    [
        (0.01, [_replay(1.0), _replay(0.95)], "success"),
        (0.01, [_replay(1.0), _replay(0.85, spilled=3)], "spill"),
        (0.01, [_replay(1.0), _replay(0.85, spilled=1)], "low_pour"),
        (0.01, [_replay(1.0), _replay(1.0, distance=-0.001)], "physics_contact"),
        (-0.002, [_replay(1.0, distance=-0.001)], "plan_collision"),
        (-0.002, [_replay(1.0, diverged=True)], "diverged"),
    ],
)
def test_outcome(plan, replays, expected):
    assert outcome(plan, replays, {"particles": 20}) == expected


def test_a_variation_whose_physics_diverges_is_recorded_and_the_next_goes_on(
    model_arrays, monkeypatch
):
    from imitate.evaluation import trial
    from imitate.motion import replay as replaying

    suite = Suite.from_dict({**TINY, "obstacle_share": 0.0, "replays": 1})
    first, second = (draw(suite, 0, i, np.zeros((2, 3))) for i in range(2))
    learned = Learned(LearnedModel.from_arrays(model_arrays), model_arrays["gaze"])
    runner = trial.Trial(learned, POUR)
    replay = replaying.replay

    def diverging(plan, env, on_step, **kwargs):
        def step(env):
            on_step(env)
            if env.data.time > 0.1:
                env.data.qvel[:] = 1e30  # blows up the next step

        return replay(plan, env, on_step=step, **kwargs)

    monkeypatch.setattr(replaying, "replay", diverging)
    record = runner.run(first)
    assert record["outcome"] == "diverged" and record["replays"][0]["diverged"]
    monkeypatch.setattr(replaying, "replay", replay)
    assert runner.run(second)["outcome"] != "diverged"


@pytest.fixture(scope="module")
def two_workers(tmp_path_factory, model_arrays):
    """The tiny suite's records on two local workers, and its summary."""
    run_dir = _run_dir(tmp_path_factory.mktemp("two"), model_arrays)
    summary = evaluate(run_dir, Suite.from_dict(TINY), workers=2, videos=0)
    return read_records(_out(run_dir) / RESULTS, summary["suite_digest"], POUR), summary


def test_tiny_evaluation_same_on_one_worker_after_a_resume(
    tmp_path, model_arrays, two_workers, monkeypatch
):
    suite = Suite.from_dict(TINY)
    run_dir = _run_dir(tmp_path, model_arrays)
    evaluate(run_dir, suite, n=2, workers=1, videos=0)
    with open(_out(run_dir) / RESULTS, "a") as f:
        f.write('{"digest": "cut sh')  # an interrupted write
    summary = evaluate(run_dir, suite, workers=1, videos=1)
    assert summary["run"]["ran"] == 1 and summary["variations"] == 3
    records = read_records(_out(run_dir) / RESULTS, summary["suite_digest"], POUR)
    assert len(records) == 3
    assert _without_timings(records) == _without_timings(two_workers[0])
    failures = sorted((_out(run_dir) / "failures" / summary["suite_digest"]).glob("*"))
    assert len(failures) == min(1, 3 - summary["outcomes"]["success"])
    assert all(p.suffix == ".mp4" and p.stat().st_size > 0 for p in failures)
    assert (_out(run_dir) / "outcomes.png").stat().st_size > 0
    saved = json.loads((_out(run_dir) / "summary.json").read_text())
    assert sum(saved["outcomes"].values()) == 3
    assert saved["suite_digest"] == summary["suite_digest"] == two_workers[1]["suite_digest"]
    monkeypatch.setattr(provenance, "code_digest", lambda: "other code")
    assert evaluate(run_dir, suite, n=1, workers=1, videos=0)["run"]["ran"] == 1  # not reused
    assert [r["id"] for r in last_records(_out(run_dir))] == [0]  # the last evaluation's only
    with pytest.raises(ImitateError, match="summary.json is missing"):
        last_records(tmp_path / "elsewhere")


def test_tiny_evaluation_same_on_ray(tmp_path, model_arrays, two_workers):
    ray = pytest.importorskip("ray")
    run_dir = _run_dir(tmp_path, model_arrays)
    ray.init(num_cpus=2, include_dashboard=False)
    try:
        summary = evaluate(run_dir, Suite.from_dict(TINY), ray="auto", videos=0)
    finally:
        ray.shutdown()
    records = read_records(_out(run_dir) / RESULTS, summary["suite_digest"], POUR)
    assert _without_timings(records) == _without_timings(two_workers[0])


def test_eval_command_errors(tmp_path, model_arrays, capsys):
    run_dir = _run_dir(tmp_path, model_arrays)
    (tmp_path / "bad.toml").write_text("replays = 0\n")
    assert main(["eval", str(run_dir), "--suite", str(tmp_path / "bad.toml")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("imitate eval: error:") and "replays=0" in err and "\n" not in err
    assert main(["eval", str(tmp_path / "nowhere"), "--n", "1"]) == 1
    assert "run directory" in capsys.readouterr().err and not (tmp_path / "nowhere").exists()
    for flags, message in (
        (["--n", "0"], "--n 0 not accepted: 1..100000"),
        (["--n", "100000000"], "--n 100000000 not accepted: 1..100000"),
        (["--collision-weight", "inf"], "collision_weight=inf not accepted"),
        (["--collision-weight", "nan"], "collision_weight=nan not accepted"),
    ):
        assert main(["eval", str(run_dir), *flags]) == 1
        assert message in capsys.readouterr().err, flags
    with pytest.raises(SystemExit):
        main(["eval", str(run_dir), "--videos", "-1"])
    assert "-1 not accepted: a whole number >= 0" in capsys.readouterr().err
    assert main(["eval", str(run_dir), "--task", "insert"]) == 1  # a model alone: the default
    assert (f"--task insert not accepted: the run in {run_dir} is of task 'pour'"
            in capsys.readouterr().err)
    with pytest.raises(ImitateError, match="the suite is of task 'insert', the run in .* 'pour'"):
        evaluate(run_dir, Suite.default("insert"), n=1, workers=1, videos=0)


def test_ctrl_c_stops_eval_and_its_workers_in_one_line(tmp_path, model_arrays, in_a_terminal):
    """Ctrl-C (SIGINT to the terminal's process group) during an evaluation on two workers:
    exit status 130, one line on stderr, no traceback, no process left; records kept."""
    run_dir = _run_dir(tmp_path, model_arrays)
    (tmp_path / "suite.json").write_text(json.dumps({**TINY, "variations": 40}))
    command = [sys.executable, "-m", "imitate", "eval", str(run_dir), "--suite",
               str(tmp_path / "suite.json"), "--workers", "2", "--videos", "0"]
    process = in_a_terminal(command, stderr=subprocess.PIPE, text=True)
    results = default_out(run_dir, "suite", Suite.from_dict({**TINY, "variations": 40})) / RESULTS
    deadline = time.monotonic() + 300
    while not (results.exists() and results.stat().st_size) and time.monotonic() < deadline:
        time.sleep(0.5)
    os.killpg(process.pid, signal.SIGINT)
    _, err = process.communicate(timeout=60)
    lines = [line for line in err.splitlines() if not line.startswith("eval:")]  # tqdm's bar
    assert process.returncode == 130, err
    assert "Traceback" not in err and len(lines) == 1, err
    assert lines[0].startswith("imitate eval: error: interrupted (Ctrl-C)"), err
    time.sleep(1)
    assert _live_processes_in_group(process.pid) == []  # the workers are gone too
    assert results.read_text().count("\n") >= 1


def _live_processes_in_group(pgid: int) -> list[int]:
    """Pids in process group ``pgid`` that are not zombies (from ``/proc/PID/stat``)."""
    live = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue  # exited meanwhile
        if int(fields[2]) == pgid and fields[0] != "Z":
            live.append(int(stat.parent.name))
    return live


def test_summary_counts_the_plans_that_keep_the_margin_and_those_pushed():
    def record(plan_mm, physics_mm, pour, pushed=False):
        return {
            "outcome": "success" if pour >= 0.9 and physics_mm >= 0 else "spill",
            "settings": {"obstacle": None, "in_path": False}, "seconds": 1.0,
            "plan": {"min_distance_m": plan_mm / 1000, "nullspace_push": pushed},
            "physics_min_distance_m": physics_mm / 1000,
            "clearance_gap_m": (plan_mm - physics_mm) / 1000, "pour_mean": pour, "pour_min": pour,
        }

    records = [
        record(12, 11, 1.0, pushed=True), record(12, -1, 1.0), record(13, 12, 0.8, pushed=True),
        record(5, -2, 0.5),
    ]
    summary = summarize(records, POUR)
    assert summary["kept_margin"] == {
        "margin_m": 0.011, "pour_threshold": 0.9, "plans": 3, "physics_contact": 1, "low_pour": 1,
    }
    run = {"ran": 4, "wall_seconds": 4.0, "backend": "local", "workers": 1,
           "load_average_start": [0.0] * 3, "load_average_end": [0.0] * 3}
    printed = text({**summary, "run": run, "suite_digest": "d"}, Path("eval"), POUR)
    assert "margin: 3; of them touching in physics 1, pour_fraction below 0.9 in a replay 1" in (
        printed)
    assert summary["nullspace_push"] == {"plans": 2, "success": 1}
    assert "plans with the null-space push: 2; of them successes 1" in printed


# --- what eval writes, and where (review S4, N-x3, E18) ----------------------------------------


def _tiny_eval(run_dir: Path, tmp_path: Path, *flags: str) -> list[str]:
    (tmp_path / "tiny.json").write_text(json.dumps(TINY))
    return ["eval", str(run_dir), "--suite", str(tmp_path / "tiny.json"), "--n", "1",
            "--workers", "1", "--videos", "0", *flags]


def _one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if not line.startswith("warning: ")]
    assert len(lines) == 1 and lines[0].startswith("imitate eval: error: "), err
    return lines[0]


def test_a_link_on_the_way_to_the_evaluation_is_refused(tmp_path, model_arrays, capsys):
    run_dir = _run_dir(tmp_path / "run", model_arrays)
    outside = tmp_path / "outside"
    outside.mkdir()
    (run_dir / "eval").symlink_to(outside, target_is_directory=True)
    assert main(_tiny_eval(run_dir, tmp_path)) == 1
    assert f"{run_dir / 'eval'} is a symbolic link" in _one_line(capsys.readouterr().err)
    assert not any(outside.iterdir())


def test_a_link_on_the_way_to_the_teachers_is_refused(tmp_path, model_arrays):
    from imitate.evaluation.teachers import teachers
    from imitate.stages.config import RunConfig

    run_dir = _run_dir(tmp_path / "run", model_arrays)
    save_json(run_dir / "config.json", RunConfig.quick().to_json())
    outside = tmp_path / "outside"
    outside.mkdir()
    (run_dir / "eval").mkdir()
    (run_dir / "eval" / "teachers").symlink_to(outside, target_is_directory=True)
    with pytest.raises(ImitateError, match="eval/teachers is a symbolic link"):
        teachers(run_dir, run_dir / "eval", 2)
    assert not any(outside.iterdir())


def test_eval_out_refuses_a_folder_holding_no_evaluation(tmp_path, model_arrays, capsys):
    run_dir = _run_dir(tmp_path / "run", model_arrays)
    folder = tmp_path / "F"
    folder.mkdir()
    (folder / "report.html").write_text("mine")
    (folder / "summary.json").write_text('{"mine": 1}')
    assert main(_tiny_eval(run_dir, tmp_path, "--out", str(folder))) == 1
    line = _one_line(capsys.readouterr().err)
    assert f"{folder} holds report.html, summary.json but no evaluation" in line
    assert "give a new or empty folder as --out" in line
    assert sorted(p.name for p in folder.iterdir()) == ["report.html", "summary.json"]
    assert (folder / "report.html").read_text() == "mine"
    (folder / "results.jsonl").write_text('{"loss": 0.1}\n')  # a common name, not an eval's
    assert main(_tiny_eval(run_dir, tmp_path, "--out", str(folder))) == 1
    assert "but no evaluation" in _one_line(capsys.readouterr().err)
    assert (folder / "results.jsonl").read_text() == '{"loss": 0.1}\n'


@pytest.mark.parametrize("notes", [b"my lab notes\nday 2\n", b""])
def test_eval_out_refuses_a_results_file_of_no_record_beside_other_files(
    tmp_path, model_arrays, notes, capsys
):
    """Review follow-up N1: a results.jsonl of someone's notes (or empty) beside a page of
    theirs is no evaluation cut short (it writes nothing before its first record)."""
    run_dir = _run_dir(tmp_path / "run", model_arrays)
    folder = tmp_path / "F"
    folder.mkdir()
    (folder / "report.html").write_text("<h1>my page</h1>")
    (folder / "results.jsonl").write_bytes(notes)
    assert main(_tiny_eval(run_dir, tmp_path, "--out", str(folder))) == 1
    assert "but no evaluation" in _one_line(capsys.readouterr().err)
    assert (folder / "report.html").read_text() == "<h1>my page</h1>"
    assert (folder / "results.jsonl").read_bytes() == notes
    (folder / "report.html").unlink()
    if notes:  # alone, still not what an evaluation leaves
        assert main(_tiny_eval(run_dir, tmp_path, "--out", str(folder))) == 1
        assert (folder / "results.jsonl").read_bytes() == notes


def test_eval_refuses_a_fifo_as_its_summary_at_once(tmp_path, model_arrays, capsys):
    """Review follow-up N2: reading a FIFO would wait for a writer, holding the run's lock."""
    run_dir = _run_dir(tmp_path / "run", model_arrays)
    folder = tmp_path / "F"
    folder.mkdir()
    os.mkfifo(folder / "summary.json")
    assert main(_tiny_eval(run_dir, tmp_path, "--out", str(folder))) == 1
    assert "summary.json is not a regular file" in _one_line(capsys.readouterr().err)


@pytest.mark.parametrize("first", [b'{"digest": "0123", "id": 0, "outc', b"\x00" * 40, b"",
                                   b'{"digest": "0123", "id": 0}'])
def test_eval_resumes_its_own_folder_cut_short_in_its_first_record(tmp_path, model_arrays,
                                                                   first):
    """Review B: a torn first line, NUL bytes, a blank line or an older record's form: the
    folder is the evaluation's own, which goes on there."""
    run_dir = _run_dir(tmp_path / "run", model_arrays)
    folder = tmp_path / "F"
    folder.mkdir()
    (folder / "results.jsonl").write_bytes(first + b"\n")
    assert main(_tiny_eval(run_dir, tmp_path, "--out", str(folder))) == 0
    assert last_records(folder)  # its records appended after what was there


def test_a_file_in_the_way_of_the_evaluation_is_named(tmp_path, model_arrays, capsys):
    run_dir = _run_dir(tmp_path / "run", model_arrays)
    (run_dir / "eval").write_text("a file")
    assert main(_tiny_eval(run_dir, tmp_path)) == 1
    line = _one_line(capsys.readouterr().err)
    assert f"{run_dir / 'eval'} is a file, in the way" in line and "run it again" not in line


@pytest.mark.parametrize("name", ["mean", "weights", "covariances"])
def test_a_model_of_nan_names_its_file(tmp_path, model_arrays, name):
    """Review I10, N-e1: the model's errors name model.npz and the stage to re-run."""
    arrays = {**model_arrays, name: np.full_like(model_arrays[name], np.nan)}
    save_npz(tmp_path / "model.npz", arrays)
    with pytest.raises(ImitateError, match=f"model.npz: {name} must be finite .*imitate learn"):
        ModelFile.load_learned(tmp_path)


def test_a_model_of_disagreeing_shapes_names_its_file(tmp_path, model_arrays):
    """Review I10: a GMR covariance of 3 dimensions beside a mean of 7 reached the planner."""
    arrays = {**model_arrays, "covariance": model_arrays["covariance"][:, :3, :3]}
    save_npz(tmp_path / "model.npz", arrays)
    with pytest.raises(ImitateError, match=r"model.npz: times \(T,\), mean .* must agree; got"):
        ModelFile.load_learned(tmp_path)


def test_a_run_directory_this_user_cannot_write_is_evaluated_into_out(
    tmp_path, model_arrays, monkeypatch, caplog
):
    """Review N-b4: read-only media or a shared run (the tests run as root, who may write
    anywhere: the directory is made unwritable for os.access, as for another user)."""
    from imitate.rundir import lock

    run_dir = _run_dir(tmp_path / "run", model_arrays)
    before = sorted(p.name for p in run_dir.iterdir())
    unwritable = os.path.abspath(run_dir)
    access = os.access
    monkeypatch.setattr(lock.os, "access", lambda path, mode, **kw: (
        os.path.abspath(path) != unwritable and access(path, mode, **kw)
    ))
    with caplog.at_level("INFO", "imitate"):
        assert main(_tiny_eval(run_dir, tmp_path, "--out", str(tmp_path / "ev"))) == 0
    assert "is read-only for this user: read without its lock" in caplog.text
    assert (tmp_path / "ev" / RESULTS).exists()
    assert sorted(p.name for p in run_dir.iterdir()) == before  # no .lock, no eval/
    with lock.locked(run_dir, "imitate learn"):  # a command that writes there takes it
        assert (run_dir / lock.LOCK).exists()


@pytest.mark.parametrize(
    "default_run, shown",
    [
        ({"pour_fractions": [1.0, 0.95], "success": True}, "1.000 0.950 (success)"),
        ("abc", "-"), ({"pour_fractions": ["x"], "success": True}, "-"),
        ({"pour_fractions": [1.0]}, "-"), (None, "-"),
    ],
)
def test_a_teachers_default_run_is_shown_only_when_it_holds_its_numbers(default_run, shown):
    """Review X10: a teacher's report.json is read as it is; a replay section of another form
    shows as "-" in the teachers' table instead of a traceback."""
    row = {"seed": 3, "default_run": default_run, "success": 1, "variations": 2,
           "success_wilson95": [0.1, 0.9], "pour_min": 0.5, "pour_min_mean": 0.6, "failures": []}
    assert f"| 3 | {shown} | 1/2 |" in teacher_table([row], POUR)


@pytest.mark.parametrize(
    "summary", [{"teachers": [], "suite_digest": ["x"]}, {"teachers": [{"digest": 3}]}]
)
def test_a_summary_whose_digests_are_not_text_is_refused_in_one_line(tmp_path, summary):
    """Review X6c: a TypeError (unhashable list) before."""
    (tmp_path / "summary.json").write_text(json.dumps(summary))
    with pytest.raises(ImitateError, match="is not an evaluation's summary .*not all text"):
        last_records(tmp_path)
