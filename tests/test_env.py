"""The Gymnasium contract of ``imitate/Pouring-v0``: spaces, determinism, rendering, bad input."""

import os
import subprocess
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import imitate
from imitate.envs.assembly import Obstacle
from imitate.envs.pouring import PouringEnv
from imitate.errors import ImitateError

SMALL = {"width": 96, "height": 72, "particles": 20}


@pytest.fixture(scope="module")
def env():
    env = gym.make(imitate.ENV_ID, render_mode="rgb_array", **SMALL)
    yield env
    env.close()


def test_check_env_state():
    env = PouringEnv(render_mode="rgb_array", **SMALL)
    check_env(env, skip_render_check=False)
    env.close()


def test_check_env_stereo():
    env = PouringEnv(obs_type="stereo", **SMALL)
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert obs["left_eye"].shape == (72, 96, 3) and obs["left_eye"].dtype == np.uint8
    assert not np.array_equal(obs["left_eye"], obs["right_eye"])  # two viewpoints
    env.close()


def _rollout(env, seed, steps=15):
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    observations, infos = [obs], []
    for _ in range(steps):
        action = env.unwrapped.data.ctrl + rng.normal(0, 0.02, env.action_space.shape)
        action = np.clip(action, env.action_space.low, env.action_space.high).astype(np.float32)
        obs, reward, terminated, truncated, info = env.step(action)
        assert np.isfinite(reward)
        observations.append(obs)
        infos.append(info)
    return np.array(observations), infos


def test_same_seed_same_trajectory(env):
    first, _ = _rollout(env, seed=7)
    second, _ = _rollout(env, seed=7)
    np.testing.assert_array_equal(first, second)
    other, _ = _rollout(env, seed=8)
    assert not np.array_equal(first[0], other[0])  # the initial state is randomised


def test_observations_finite_and_in_space(env):
    observations, infos = _rollout(env, seed=3)
    assert np.all(np.isfinite(observations))
    assert all(obs in env.observation_space for obs in observations)
    assert not np.shares_memory(observations[0], env.unwrapped.data.qpos)
    for info in infos:
        assert {"reward_pour", "reward_collision", "is_success", "min_distance"} <= set(info)
        assert info["is_success"] is False  # nothing has been poured
    assert np.ptp(observations[:, :18], axis=0).max() > 0  # the robot moved


@pytest.mark.parametrize("camera", ["overview", "left_eye", "right_eye"])
def test_rendered_frame_is_not_blank(camera):
    env = PouringEnv(render_mode="rgb_array", camera=camera, **SMALL)
    env.reset(seed=0)
    frame = env.render()
    env.close()
    assert frame.shape == (72, 96, 3) and frame.dtype == np.uint8
    assert frame.std() > 10


def test_reset_options_move_the_grasp(env):
    env.reset(seed=0, options={"bottle_grasp": 0.06})
    low = env.unwrapped.data.body("bottle").xpos[2]
    env.reset(seed=0, options={"bottle_grasp": 0.12})
    assert env.unwrapped.data.body("bottle").xpos[2] < low - 0.05


def test_obstacle_option():
    box = Obstacle("box", (0.75, 0.0, 0.7), (0.05, 0.05, 0.05))
    env = PouringEnv(obstacles=(box,), **SMALL)
    _, info = env.reset(seed=0)
    assert env.model.geom("obstacle_0").size[2] == pytest.approx(0.05)
    assert info["min_distance"] > 0


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"particles": -3}, "particles=-3"),
        ({"obs_type": "pixels"}, "obs_type='pixels'"),
        ({"camera": "top"}, "camera='top'"),
        ({"render_mode": "human"}, "render_mode='human'"),
        ({"frame_skip": 0}, "frame_skip=0"),
        ({"width": -5}, "width=-5"),
        ({"reset_noise_scale": -0.1}, "reset_noise_scale=-0.1"),
        (
            {"obstacles": ({"shape": "box", "pos": (0.6, 0, 0.3), "size": (0.1, 0.1, 0.1)},)},
            "table",
        ),
        ({"obstacles": ("box",)}, "obstacles must be"),
    ],
)
def test_bad_constructor_arguments(kwargs, match):
    with pytest.raises(ImitateError, match=match):
        PouringEnv(**{**SMALL, **kwargs})


def test_bad_reset_options(env):
    with pytest.raises(ImitateError, match=r"unknown; accepted: \['bottle_grasp'"):
        env.reset(options={"bottle_height": 0.1})
    with pytest.raises(ImitateError, match="bottle grasp height -0.1"):
        env.reset(options={"bottle_grasp": -0.1})


def test_bad_action(env):
    env.reset(seed=0)
    with pytest.raises(ImitateError, match=r"action of shape \(3,\) not accepted: \(18,\)"):
        env.step(np.zeros(3))
    with pytest.raises(ImitateError, match="finite"):
        env.step(np.full(18, np.nan))


def test_too_large_render_size():
    env = PouringEnv(render_mode="rgb_array", width=4000, height=72, particles=0)
    env.reset(seed=0)
    with pytest.raises(ImitateError, match="width must be in 1..1280"):
        env.render()


def test_unusable_mujoco_gl():
    code = "import imitate"
    result = subprocess.run(
        [sys.executable, "-c", code],
        check=False,
        env={**os.environ, "MUJOCO_GL": "vulkan"},
        capture_output=True,
        text=True,
    )
    assert result.returncode != 0
    assert "MUJOCO_GL='vulkan' is not a usable backend" in result.stderr
    assert "'egl'" in result.stderr and "'osmesa'" in result.stderr
