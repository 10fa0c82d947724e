"""Minari datasets (Farama's standard for offline RL): one for the robot, one for the teacher.

Under the root directory (Minari's ``MINARI_DATASETS_PATH``), named by the task's env id
(:func:`dataset_ids`): the robot's, whose env spec is the task's env id with the run's kwargs
(``dataset.recover_environment()`` makes it), and the teacher's, which comes from no env (its
spaces are stored, its env spec is not). Both
carry ``requirements`` (this package's distribution and MuJoCo, pinned: the physics replays bit
for bit only there; ``recover_environment()`` warns about others) and, in their description, the
code's digest (:func:`imitate.stages.provenance.code_digest`, as a run's files name it). Their
``code_permalink`` is left empty: the distribution has no public release to point to.
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import gymnasium as gym
import minari
import mujoco
import numpy as np
from minari.data_collector import EpisodeBuffer

from imitate import __version__
from imitate.export.episodes import Episode
from imitate.stages import provenance

__all__ = ["DISTRIBUTION", "dataset_ids", "write"]

_METADATA = {"author": "imitate", "algorithm_name": "imitate (Muehlig et al., ICRA 2009)"}
DISTRIBUTION = "imitate-humanoid"  # pyproject.toml's project name (the import name is imitate)


def dataset_ids(env_id: str) -> tuple[str, str]:
    """The robot's and the teacher's dataset ids of a task whose env id is ``env_id``:
    ``imitate/Name-v0`` gives ``imitate/name/robot-v0`` and ``imitate/name/teacher-v0``."""
    name = env_id.split("/")[-1].rsplit("-", 1)[0].lower()
    return f"imitate/{name}/robot-v0", f"imitate/{name}/teacher-v0"


def write(root: Path, robot: Iterable[Episode], teacher: Iterable[Episode]) -> None:
    """Write both datasets under ``root`` (:func:`dataset_ids` of the robot's env); the robot's
    episode is one (its env spec the dataset's)."""
    (episode,) = robot
    env_id = episode.env.id if episode.env is not None else ""
    robot_id, teacher_id = dataset_ids(env_id)
    metadata = {
        **_METADATA,
        "requirements": [f"{DISTRIBUTION}=={__version__}", f"mujoco=={mujoco.__version__}"],
    }
    made = f" Made by {DISTRIBUTION} {__version__}, code sha256 {provenance.code_digest()}."
    with _datasets_path(root), warnings.catch_warnings():
        # Metadata this project has no value for (an e-mail address, an eval env, a release).
        warnings.filterwarnings("ignore", message=r"`(author_email|eval_env|code_permalink)`")
        warnings.filterwarnings("ignore", message="env_spec is None")  # the teacher has no env
        minari.create_dataset_from_buffers(
            robot_id, [_buffer(episode)], env=episode.env, **metadata,
            description=f"The robot is to {episode.instruction}: the optimized plan replayed in "
            f"{env_id}. Actions: joint position targets [rad] (float64, as given to env.step); "
            "the last step is truncated by the spec's time limit." + made,
        )
        episodes = iter(teacher)
        first = next(episodes)
        objects = " and ".join(first.environment)
        dataset = minari.create_dataset_from_buffers(
            teacher_id, [_buffer(first)], **metadata,
            observation_space=gym.spaces.Dict({
                key: _space(value) for key, value in first.observations.items()
            }),
            action_space=_space(first.actions),
            description=f"The teacher's demonstrations ({first.instruction}) as the robot cut "
            f"them. Observations: task (the task space of the tracked objects), {objects} (true "
            f"frames: position [m], quaternion wxyz). Actions: the next frame's true {objects}; "
            "rewards 0." + made,
        )
        for episode in episodes:  # one at a time: with images an episode is large
            dataset.update_dataset_from_buffer([_buffer(episode)])


def _buffer(episode: Episode) -> EpisodeBuffer:
    observations: dict[str, Any] | np.ndarray
    observations = episode.observations
    if episode.env is not None:  # as the env returns them: a state vector, with images a dict
        state = np.hstack([v for k, v in observations.items() if k not in episode.images])
        images = {camera: observations[camera] for camera in episode.images}
        observations = {"state": state, "pixels": images} if images else state
    return EpisodeBuffer(
        seed=episode.seed, options=episode.options, observations=observations,
        actions=episode.actions, rewards=episode.rewards, terminations=episode.terminations,
        truncations=episode.truncations, infos=episode.infos,
    )


def _space(values: np.ndarray) -> gym.spaces.Box:
    """The space of one step of ``values`` ``(n, ...)``: images 0..255, vectors unbounded."""
    if values.dtype == np.uint8:
        return gym.spaces.Box(0, 255, values.shape[1:], dtype=np.uint8)
    return gym.spaces.Box(-np.inf, np.inf, values.shape[1:], dtype=np.float64)


@contextlib.contextmanager
def _datasets_path(root: Path):
    """Minari's datasets root set to ``root`` while inside."""
    before = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(root.absolute())  # Minari joins a relative one twice
    try:
        yield
    finally:
        if before is None:
            del os.environ["MINARI_DATASETS_PATH"]
        else:
            os.environ["MINARI_DATASETS_PATH"] = before
