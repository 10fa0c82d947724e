"""RunConfig's value checks and the CLI's one-line refusals of them; the push and teacher
settings' way to the planner, the teacher and the manifest."""

import dataclasses
import json

import imageio.v3 as iio
import numpy as np
import pytest

from imitate.cli import main
from imitate.cli.parser import build_parser, config_for
from imitate.defaults import MAX_WEIGHT
from imitate.envs import tasks
from imitate.envs.teacher_motion import TeacherConfig
from imitate.envs.video import write_video
from imitate.errors import ImitateError
from imitate.stages import provenance, table
from imitate.stages.config import (
    VIDEO_BLOCK,
    RunConfig,
    load_config,
    parse_obstacle,
)


@pytest.mark.parametrize(
    "values, match",
    [
        ({"seed": -1}, "seed=-1 not accepted: a finite value >= 0"),
        ({"collision_weight": 1e300}, r"collision_weight=1e\+300 not accepted: .* 0\.\.1e\+06"),
        ({"sweep": (0.1, 1e300)}, r"sweep=\(0\.1, 1e\+300\) not accepted: .* 0\.\.1"),
        ({"video_width": 65}, r"video_width=65 not accepted: .* of 8 \(nearest: 64, 72\)"),
        ({"video_height": 49}, r"video_height=49 not accepted: .*\(nearest: 48, 56\)"),
        ({"video_height": 1090}, r"video_height=1090 not accepted: a value in 48\.\.1080, a"),
    ],
)
def test_bad_values_are_refused(values, match):
    with pytest.raises(ImitateError, match=match):
        RunConfig(**values)


def test_bounds_are_in_the_help():
    assert f"0..{MAX_WEIGHT:g}" in RunConfig.__doc__
    assert f"64..1920, a multiple of {VIDEO_BLOCK}" in RunConfig.__doc__
    RunConfig(collision_weight=MAX_WEIGHT, seed=2**70)  # the edges are accepted


@pytest.mark.parametrize(
    "text",
    [
        "box:0.55,0.0,nan:0.03,0.03,0.05",
        "box:0.55,0.0,inf:0.03,0.03,0.05",
        "box:0.55,0.0,0.70:nan,0.03,0.05",
        "box:0.55,0.0,0.70:0.03,inf,0.05",
        "cylinder:0.55,0,nan:0.03,0.05",
    ],
)
def test_non_finite_obstacle_is_refused(text):
    with pytest.raises(ImitateError, match="finite"):
        parse_obstacle(text)


def test_obstacle_on_the_robot_is_refused():
    with pytest.raises(ImitateError, match="overlaps 'right_hand'"):
        RunConfig(obstacle=parse_obstacle("box:0.45,-0.17,0.70:0.05,0.05,0.09"))
    RunConfig(obstacle=parse_obstacle("box:0.55,0.0,0.70:0.03,0.03,0.05"))  # the README's


@pytest.mark.parametrize(
    "argv, expected",
    [
        (["--seed", "-1"], "seed=-1 not accepted"),
        (["--collision-weight", "1e300"], "collision_weight=1e+300 not accepted"),
        (["--video-width", "65"], "(nearest: 64, 72)"),
        (["--obstacle", "box:0.55,0.0,nan:0.03,0.03,0.05"], "finite"),
        (["--obstacle", "box:0.78,0,2.61:2,2,2"], "footprint"),
        (["--obstacle", "box:0.45,-0.17,0.70:0.05,0.05,0.09"], "overlaps 'right_hand'"),
    ],
)
def test_cli_refuses_in_one_line(argv, expected, tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["run", "--quick", *argv, "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.splitlines()
    assert expected in err[-1] and "Traceback" not in "\n".join(err)
    assert not (tmp_path / "config.json").exists()


def test_video_has_the_accepted_size(tmp_path):
    """The encoder keeps a size that is a multiple of ``VIDEO_BLOCK`` (it pads any other)."""
    width, height = 9 * VIDEO_BLOCK, 7 * VIDEO_BLOCK
    frames = [np.full((height, width, 3), 40 * i, np.uint8) for i in range(3)]
    write_video(tmp_path / "v.mp4", frames, fps=10)
    assert iio.imread(tmp_path / "v.mp4").shape == (3, height, width, 3)


def _parsed(*argv: str) -> RunConfig:
    args = build_parser().parse_args(list(argv))
    return config_for(args, RunConfig())


def test_push_and_teacher_variation_flags_reach_the_planner_and_the_teacher():
    default = _parsed("run")
    assert default.push and default.plan_config().nullspace_push
    assert default.teacher_variation == "aligned" and default.teacher().variation == "aligned"
    assert default.teacher() == TeacherConfig(n_demos=5, seed=0)  # today's teacher
    off = _parsed("optimize", "--no-push")
    assert not off.push and not off.plan_config().nullspace_push
    assert _parsed("run", "--push").push
    swapped = _parsed("run", "--teacher-variation", "misaligned", "--no-push")
    assert swapped.teacher().variation == "misaligned" and not swapped.push
    assert _parsed("observe", "--teacher-variation", "misaligned").teacher_variation == "misaligned"


def test_cli_refuses_an_unknown_teacher_variation(tmp_path, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["run", "--quick", "--teacher-variation", "sideways", "--out", str(tmp_path)])
    assert exit_info.value.code == 2
    assert "misaligned" in capsys.readouterr().err.splitlines()[-1]


def test_push_and_teacher_variation_are_recorded_and_rerun_their_stages(tmp_path):
    """config.json keeps both; the manifest records ``push`` with the optimize stage (changing
    it outdates the plan, not the demonstrations) and ``teacher_variation`` with observe (it
    outdates everything after it). A run recorded before the settings existed is not outdated
    by them at their defaults."""
    config = RunConfig(push=False, teacher_variation="misaligned")
    assert RunConfig.from_json(json.loads(json.dumps(config.to_json()))) == config
    manifest: dict = {}
    for name, output in (("observe", "demos.npz"), ("optimize", "plan.npz")):
        (tmp_path / output).write_bytes(name.encode())
        manifest = provenance.recorded(
            manifest, tmp_path, table.find(name), config, {output: tmp_path / output}
        )
    assert manifest["optimize"]["settings"]["push"] is False
    assert "push" not in manifest["observe"]["settings"]
    assert manifest["observe"]["settings"]["teacher_variation"] == "misaligned"
    assert provenance.outdated(tmp_path, config, manifest) == {}
    pushed = dataclasses.replace(config, push=True)
    assert provenance.outdated(tmp_path, pushed, manifest) == {
        "optimize": "made with push=False, not True"
    }
    aligned = dataclasses.replace(config, teacher_variation="aligned")
    assert set(provenance.outdated(tmp_path, aligned, manifest)) == {"observe", "optimize"}
    for record in manifest.values():  # as recorded before the settings existed
        for name in ("push", "teacher_variation"):
            record["settings"].pop(name, None)
    assert provenance.outdated(tmp_path, RunConfig(), manifest) == {}
    (tmp_path / "config.json").write_text(json.dumps({"seed": 0, "n_demos": 5}))
    old = load_config(tmp_path)
    assert old.push and old.teacher_variation == "aligned"


def test_a_config_json_written_before_the_task_was_a_setting_is_the_default_tasks(tmp_path):
    """Its task's own settings stood among the others: they are read as the default task's."""
    old = {k: v for k, v in RunConfig().to_json().items() if k not in ("task", "options")}
    (tmp_path / "config.json").write_text(json.dumps({**old, "particles": 40}))
    config = load_config(tmp_path)
    assert config.task == tasks.DEFAULT and config.options["particles"] == 40
    assert config == RunConfig(options={"particles": 40})
