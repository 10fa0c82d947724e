"""Whether an RL user's exploration breaks the physics: uniform random actions in each task's env.

    python scripts/experiments/random_actions.py [--episodes 100] [--steps 500]
        [--task pour,insert] [--max-target-speed 10,inf]

For each task and each ``max_target_speed`` (the env's argument, rad/s; ``inf``: the targets
jump to each action), ``--episodes`` episodes of up to ``--steps`` steps of
``env.action_space.sample()`` (reset and action space seeded by the episode's index). Prints per
arm the episodes that diverged (``info["diverged"]``), the step at which they did (median), the
largest joint speed seen in the others [rad/s], the furthest a joint went past its limit [rad]
(MuJoCo's limits are soft), the steps at which one went further than the observation space's
``JOINT_SLACK`` (its observed angle then clipped to it), and the env steps per second.
"""

from __future__ import annotations

import argparse
import math
import time

import gymnasium as gym
import numpy as np

from imitate.envs import tasks
from imitate.envs.bimanual import JOINT_SLACK
from imitate.envs.task import get_task


def explore(task: str, speed: float, episodes: int, steps: int) -> dict:
    """Random-action episodes of ``task``'s env at ``max_target_speed=speed``."""
    env = gym.make(get_task(task).env_id, max_target_speed=speed, max_episode_steps=steps)
    joints = env.unwrapped._joint_dof
    low, high = env.unwrapped.action_space.low, env.unwrapped.action_space.high  # joint limits
    diverged_at, fastest, past, clipped, n_steps = [], 0.0, 0.0, 0, 0
    start = time.perf_counter()
    for episode in range(episodes):
        env.reset(seed=episode)
        env.action_space.seed(episode)
        for step in range(steps):
            _, _, _, truncated, info = env.step(env.action_space.sample())
            n_steps += 1
            angles = env.unwrapped.joint_positions()
            beyond = float(np.max(np.maximum(low - angles, angles - high)))
            past, clipped = max(past, beyond), clipped + (beyond > JOINT_SLACK)
            if info["diverged"]:
                diverged_at.append(step + 1)
                break
            fastest = max(fastest, float(np.abs(env.unwrapped.data.qvel[joints]).max()))
            if truncated:
                break
    env.close()
    return {
        "diverged": len(diverged_at),
        "at": float(np.median(diverged_at)) if diverged_at else math.nan,
        "fastest": fastest,
        "past": past,
        "clipped": clipped,
        "rate": n_steps / (time.perf_counter() - start),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--task", default=",".join(tasks.NAMES))
    parser.add_argument("--max-target-speed", default="10,inf")
    args = parser.parse_args()
    speeds = [float(s) for s in args.max_target_speed.split(",")]
    print(f"{args.episodes} episodes of up to {args.steps} steps of uniform random actions\n")
    print("| task | max_target_speed [rad/s] | diverged | at step (median) "
          "| fastest joint otherwise [rad/s] | furthest past a limit [rad] "
          "| steps past the slack | steps/s |")
    print("|---|---|---|---|---|---|---|---|")
    for task in args.task.split(","):
        for speed in speeds:
            r = explore(task, speed, args.episodes, args.steps)
            print(f"| {task} | {speed:g} | {r['diverged']} of {args.episodes} | {r['at']:g} "
                  f"| {r['fastest']:.1f} | {r['past']:.3f} | {r['clipped']} "
                  f"| {r['rate']:.0f} |", flush=True)


if __name__ == "__main__":
    main()
