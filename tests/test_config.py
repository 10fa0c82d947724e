"""RunConfig's value checks and the CLI's one-line refusals of them."""

import imageio.v3 as iio
import numpy as np
import pytest

from imitate.cli import main
from imitate.envs.video import write_video
from imitate.errors import ImitateError
from imitate.stages.config import MAX_WEIGHT, VIDEO_BLOCK, RunConfig, parse_obstacle


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
