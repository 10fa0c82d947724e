"""Env steps per second of each task with state and with pixel observations, in one run: what
an agent learning from pixels pays for them.

    python scripts/bench/bench_env_rates.py [--steps 200] [--size 96]

For each task's Gymnasium env (``gym.make``), ``--steps`` steps after a reset, each action the
reset posture's joint targets plus noise of 0.05 rad (an agent exploring near the posture),
with ``obs_type="state"``, then ``"pixels"`` at ``--size`` square with ``render_quality="fast"``
(the default) and ``"full"``. Prints the steps per second (wall clock, one thread) and the ratio
to the state observations' rate, and which OpenGL renderer drew the pixels (Mesa's llvmpipe on a
CPU, the GPU's name where ``MUJOCO_GL=egl`` finds one).
"""

from __future__ import annotations

import argparse
import os
import time

import gymnasium as gym
import mujoco
import numpy as np

from imitate.envs import tasks
from imitate.envs.task import get_task


def rate(env_id: str, steps: int, **kwargs) -> float:
    """Steps per second of ``steps`` steps of ``env_id`` made with ``kwargs``."""
    env = gym.make(env_id, **kwargs)
    env.reset(seed=0)
    rest = env.unwrapped.data.ctrl.astype(np.float32)
    noise = np.random.default_rng(0).uniform(-0.05, 0.05, (steps, len(rest))).astype(np.float32)
    start = time.perf_counter()
    for k in range(steps):
        env.step(np.clip(rest + noise[k], env.action_space.low, env.action_space.high))
    seconds = time.perf_counter() - start
    env.close()
    return steps / seconds


def gl_renderer() -> str:
    """The OpenGL renderer's name, as the driver gives it (``GL_RENDERER``)."""
    renderer = mujoco.Renderer(mujoco.MjModel.from_xml_string("<mujoco/>"), 8, 8)
    from OpenGL import GL  # imported once the context exists: its platform follows MUJOCO_GL

    name = GL.glGetString(GL.GL_RENDERER).decode()
    renderer.close()
    return name


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--size", type=int, default=96)
    args = parser.parse_args()
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; "
          f"MUJOCO_GL={os.environ.get('MUJOCO_GL')} ({gl_renderer()}); {args.steps} steps each")
    print(f"{'env':24s} {'observation':34s} {'steps/s':>8s} {'of state':>9s}")
    size = {"width": args.size, "height": args.size}
    for name in tasks.NAMES:
        env_id = f"imitate:{get_task(name).env_id}"
        state = rate(env_id, args.steps, obs_type="state")
        print(f"{env_id:24s} {'state':34s} {state:8.1f} {1.0:9.2f}")
        for quality in ("fast", "full"):
            pixels = rate(env_id, args.steps, obs_type="pixels", render_quality=quality, **size)
            label = f"pixels {args.size}x{args.size}, render_quality={quality}"
            print(f"{env_id:24s} {label:34s} {pixels:8.1f} {pixels / state:9.2f}")


if __name__ == "__main__":
    main()
