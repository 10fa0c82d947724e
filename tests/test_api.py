"""``imitate.load_run``: the README's example, the members, their errors, the report's schema."""

import re
import shutil
import warnings
from pathlib import Path

import numpy as np
import pytest

import imitate
from imitate.envs.assembly import Obstacle
from imitate.envs.pour.env import PouringEnv
from imitate.envs.task import get_task
from imitate.learning import LearnedModel
from imitate.motion import Plan
from imitate.perception import Observations
from imitate.stages.config import RunConfig, load_config
from imitate.stages.files import DemosFile, Recording
from imitate.stages.runner import run_keys

README = Path(__file__).resolve().parents[1] / "README.md"
MARKER = "<!-- tests/test_api.py runs the next code block -->"


def readme_examples() -> list[str]:
    """The README's code blocks that follow the marker, in order."""
    found = re.findall(re.escape(MARKER) + r"\s*```python\n(.*?)```", README.read_text(), re.DOTALL)
    assert len(found) >= 2, f"README.md lacks the code blocks after {MARKER}"
    return found


def test_readme_examples_run_as_written(quick_run, tmp_path, monkeypatch, capsys):
    (tmp_path / "runs").mkdir()
    (tmp_path / "runs" / "latest").symlink_to(quick_run)
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MINARI_DATASETS_PATH", "restored after the test")
    data, api = readme_examples()
    exec(compile(data, str(README), "exec"), {"__name__": "readme"})
    assert (tmp_path / "datasets" / "imitate" / "pouring" / "robot-v0").is_dir()
    exec(compile(api, str(README), "exec"), {"__name__": "readme"})
    printed = capsys.readouterr().out
    assert re.search(r"dz varies by 2 sigma = \d+ to \d+ mm", printed), printed
    assert re.search(r"clearance -?\d+\.\d mm, pour \d\.\d\d", printed), printed
    assert re.search(r"without the collision cost -?\d+\.\d mm", printed), printed


def test_replan_plays_in_the_env_as_the_replay_stage_does(quick_run):
    run = imitate.load_run(quick_run)
    again = run.replan()  # the run's settings: the stage's plan, bit for bit
    assert np.array_equal(again.q, run.plan.q) and again.min_distance == run.plan.min_distance
    env = PouringEnv(particles=0)
    env.reset(seed=0)
    steps = imitate.actions(run.plan, env)
    assert steps.shape == (len(steps), 18) and np.all(np.isfinite(steps))
    assert all(env.action_space.contains(step) for step in steps)  # its dtype and bounds
    duration = run.plan.times[-1] - run.plan.times[0]
    assert len(steps) == round((1.0 + duration + 1.5) / env.dt) + 1  # approach, plan, settle
    with pytest.raises(imitate.ImitateError, match=r"plan setting\(s\) \['colision_weight'\]"):
        run.replan(colision_weight=0.0)
    with pytest.raises(imitate.ImitateError, match="overlaps"):
        run.replan(obstacles=[Obstacle("box", (0.45, -0.17, 0.70), (0.05, 0.05, 0.09))])
    assert {"load_run", "learn", "reproduce", "actions"} <= set(dir(imitate))


def test_members_are_typed_and_read_lazily(quick_run):
    run = imitate.load_run(quick_run)
    assert run.__dict__.keys() == {"path"}  # nothing read yet
    assert isinstance(run.config, RunConfig) and run.config == load_config(quick_run)
    assert isinstance(run.observations, Observations)
    assert isinstance(run.demos, DemosFile)
    assert len(run.demos.segments) == run.report["demos"]["detected"]
    assert isinstance(run.model, LearnedModel) and isinstance(run.plan, Plan)
    assert isinstance(run.replay, Recording)
    assert run.replay.pour_fraction == run.report["replay"]["pour_fraction"]
    assert run.replay.times.shape == (len(run.replay.qpos),)
    assert run.report["schema"] == 1
    assert run.model is run.model  # read once


def test_predict_is_the_gmr_at_any_time(quick_run):
    model = imitate.load_run(quick_run).model
    mean, covariance = model.predict(model.times)
    np.testing.assert_allclose(mean, model.mean, rtol=0, atol=1e-12)
    np.testing.assert_allclose(covariance, model.covariance, rtol=0, atol=1e-12)
    between = (model.times[3] + model.times[4]) / 2
    mean, covariance = model.predict(between)
    assert mean.shape == (1, 7) and covariance.shape == (1, 7, 7)
    assert np.all(np.linalg.eigvalsh(covariance[0]) > 0)
    for bad in ("soon", [[0.0, 1.0]], [np.nan]):
        with pytest.raises(imitate.ImitateError, match="t must"):
            model.predict(bad)


def test_missing_artifacts_name_the_file_and_the_stage(quick_run, tmp_path):
    run_dir = tmp_path / "run"
    shutil.copytree(quick_run, run_dir, ignore=shutil.ignore_patterns("plan.npz", "*.mp4"))
    run = imitate.load_run(run_dir)
    assert run.model.gmm.n_components >= 1
    with pytest.raises(imitate.ImitateError, match=r"plan\.npz is missing; re-run `imitate optim"):
        _ = run.plan
    (run_dir / "report.json").write_text("{")
    with pytest.raises(imitate.ImitateError, match=r"report\.json is corrupt .*delete it"):
        _ = run.report
    with pytest.raises(imitate.ImitateError, match="not found"):
        imitate.load_run(tmp_path / "nothing")


def report_keys(value, prefix: str = "") -> set[str]:
    """Dotted keys of a report: ``a.b``, ``a[].b`` in lists; ``timings`` and ``artifacts`` by
    their documented placeholders."""
    placeholders = {"timings": "<stage>", "artifacts": "<name>"}
    if isinstance(value, dict):
        keys = set()
        for key, item in value.items():
            name = placeholders.get(prefix, key)
            keys |= report_keys(item, f"{prefix}.{name}" if prefix else name)
        return keys
    if isinstance(value, list) and value and isinstance(value[0], dict):
        return set().union(*(report_keys(item, prefix + "[]") for item in value))
    return {prefix}


def test_every_report_key_is_documented(quick_run):
    run = imitate.load_run(quick_run)
    assert report_keys(run.report) == set(run_keys(get_task(run.config.task))[0])


def test_results_print_in_a_few_lines_with_their_shapes(quick_run):
    run = imitate.load_run(quick_run)
    for result in (run, run.model, run.plan, run.replay, run.demos):
        text = repr(result)
        assert "\n" not in text and len(text) < 300 and "array(" not in text, text
    assert f"mean {run.model.mean.shape}" in repr(run.model)
    assert f"q {run.plan.q.shape}" in repr(run.plan)


def test_predict_outside_the_movement_warns(quick_run):
    model = imitate.load_run(quick_run).model
    with pytest.warns(UserWarning, match="outside the movement's"):
        model.predict(model.times[-1] + 1.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model.predict(model.times)
