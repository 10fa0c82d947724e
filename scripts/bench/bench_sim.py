"""Benchmark the simulation: physics steps per second (with and without liquid particles) and
stereo frame pairs per second from the robot's head cameras, printed as a table: with and without
shadows, and as the observation stage renders them (``ObservationConfig.fast_render``: no
shadows, reflections, multisampling, skybox or textures).

    python scripts/bench/bench_sim.py [--seconds 3] [--pairs 20]
"""

from __future__ import annotations

import argparse
import itertools
import os
import platform
import time

import mujoco

from imitate.envs.observation import ObservationConfig, frames, session
from imitate.envs.pour.env import PouringEnv
from imitate.envs.rendering import backend, make_renderer
from imitate.models import humanoid


def physics_rate(particles: int, seconds: float) -> tuple[float, float]:
    """Physics steps per second and real-time factor, robot holding still, liquid settling."""
    env = PouringEnv(particles=particles)
    env.reset(seed=0)
    n_steps = round(seconds / env.model.opt.timestep)
    start = time.perf_counter()
    mujoco.mj_step(env.model, env.data, nstep=n_steps)
    elapsed = time.perf_counter() - start
    return n_steps / elapsed, seconds / elapsed


def stereo_rate(width: int, height: int, pairs: int, shadows: bool) -> float:
    """Stereo pairs per second rendered from the two head cameras (scene update + readback)."""
    env = PouringEnv(particles=60, width=width, height=height)
    env.reset(seed=0)
    renderer = make_renderer(env.model, height, width, shadows=shadows)
    for camera in (humanoid.LEFT_EYE, humanoid.RIGHT_EYE):  # warm-up
        renderer.update_scene(env.data, camera)
        renderer.render()
    start = time.perf_counter()
    for _ in range(pairs):
        for camera in (humanoid.LEFT_EYE, humanoid.RIGHT_EYE):
            renderer.update_scene(env.data, camera)
            renderer.render()
    elapsed = time.perf_counter() - start
    renderer.close()
    return pairs / elapsed


def observation_rate(width: int, height: int, pairs: int) -> float:
    """Stereo pairs per second as :func:`envs.observation.frames` renders the teacher's session
    (its default fast settings)."""
    sess = session(ObservationConfig(width=width, height=height))
    stream = frames(sess)
    next(stream)  # warm-up: the renderer's context is made here
    start = time.perf_counter()
    for _ in itertools.islice(stream, pairs):
        pass
    return pairs / (time.perf_counter() - start)


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="simulated time per run [s]")
    parser.add_argument("--pairs", type=int, default=20, help="stereo pairs rendered per size")
    args = parser.parse_args(argv)
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores; "
        f"MUJOCO_GL={backend()}; mujoco {mujoco.__version__}"
    )
    print(f"{'measurement':<40} {'rate':>12} {'real time':>10}")
    for particles in (0, 60):
        rate, factor = physics_rate(particles, args.seconds)
        label = f"physics, {particles} particles"
        print(f"{label:<40} {rate:>8.0f} st/s {factor:>9.1f}x")
    for (width, height), shadows in itertools.product(((640, 480), (320, 240)), (True, False)):
        rate = stereo_rate(width, height, args.pairs, shadows)
        label = f"stereo render {width}x{height}, shadows {'on' if shadows else 'off'}"
        print(f"{label:<40} {rate:>6.1f} pairs/s {'':>10}")
    for width, height in ((640, 480), (320, 240)):
        rate = observation_rate(width, height, args.pairs)
        label = f"observation render {width}x{height} (fast)"
        print(f"{label:<40} {rate:>6.1f} pairs/s {'':>10}")


if __name__ == "__main__":
    main()
