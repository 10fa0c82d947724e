"""robomimic-style HDF5: ``robot.hdf5`` (one demonstration) and ``teacher.hdf5`` (one per
demonstration).

Each file: ``data/demo_N/obs/<key>`` and ``next_obs/<key>`` ``(num_samples, ...)``, ``actions``,
``rewards``, ``dones`` (1 on the last step), ``infos/<key>`` (after each step), ``states``
``(num_samples, k)`` for the robot (MuJoCo's integration state at each ``obs``, see
:data:`~imitate.export.episodes.STATE_SPEC`: ``mj_setState`` and the step's action continue the
physics bit for bit; ``data.attrs["state_spec"]`` is the spec); the attributes
``data/demo_N.attrs["num_samples"]`` (and ``seed``, ``options`` as JSON where the episode has a
reset, ``metadata`` as JSON where it has any, e.g. an evaluated variation's settings and
outcome), ``data.attrs["total"]`` and ``data.attrs["env_args"]``: JSON ``{"env_name", "type",
"env_kwargs"}`` with robomimic's gym type (2) and the ``gym.make`` arguments every demonstration
shares (those of one variation are in its ``metadata``), or ``"env_name": null`` for the
teacher. ``mask/train`` and ``mask/valid`` hold robomimic's filter keys (demonstration names,
bytes): a seeded tenth of the demonstrations (rounded down, as robomimic's ``split_train_val``)
for validation, the rest for training. Images are gzip-compressed.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from imitate.export.episodes import STATE_SPEC, Episode

__all__ = ["GYM_TYPE", "VALID_SHARE", "write"]

GYM_TYPE = 2  # robomimic's EnvType.GYM_TYPE
VALID_SHARE = 0.1  # of the demonstrations in mask/valid (robomimic's default val_ratio)


def write(out: Path, robot: Iterable[Episode], teacher: Iterable[Episode]) -> None:
    """Write ``out/robot.hdf5`` and ``out/teacher.hdf5``, a demonstration at a time."""
    _write(out / "robot.hdf5", robot)
    _write(out / "teacher.hdf5", teacher)


def _write(path: Path, episodes: Iterable[Episode]) -> None:
    with h5py.File(path, "w") as f:
        data = f.create_group("data")
        total, kwargs, env = 0, [], None
        for i, episode in enumerate(episodes):
            _write_demo(data.create_group(f"demo_{i}"), episode)
            total += len(episode)
            if episode.states is not None and "state_spec" not in data.attrs:
                data.attrs["state_spec"] = int(STATE_SPEC)
            if episode.env is not None:
                env = episode.env
                kwargs.append({**env.kwargs, "max_episode_steps": env.max_episode_steps})
        env_args: dict[str, Any] = {"env_name": None, "type": None, "env_kwargs": {}}
        if env is not None:
            shared = {k: v for k, v in kwargs[0].items() if all(o.get(k) == v for o in kwargs)}
            env_args = {"env_name": env.id, "type": GYM_TYPE, "env_kwargs": shared}
        data.attrs["total"] = total
        data.attrs["env_args"] = json.dumps(env_args)
        names = np.array([f"demo_{i}" for i in range(len(data))], dtype="S")
        valid = np.zeros(len(names), dtype=bool)
        n_valid = int(VALID_SHARE * len(names))
        valid[np.random.default_rng(0).permutation(len(names))[:n_valid]] = True
        f.create_dataset("mask/train", data=names[~valid])
        f.create_dataset("mask/valid", data=names[valid])


def _write_demo(demo: h5py.Group, episode: Episode) -> None:
    for key, values in episode.observations.items():
        compression = "gzip" if values.dtype == np.uint8 else None
        demo.create_dataset(f"obs/{key}", data=values[:-1], compression=compression)
        demo.create_dataset(f"next_obs/{key}", data=values[1:], compression=compression)
    demo.create_dataset("actions", data=episode.actions)
    if episode.states is not None:
        demo.create_dataset("states", data=episode.states[:-1])
    demo.create_dataset("rewards", data=episode.rewards)
    demo.create_dataset("dones", data=(episode.terminations | episode.truncations).astype(int))
    for key, values in episode.infos.items():
        demo.create_dataset(f"infos/{key}", data=values[1:])
    demo.attrs["num_samples"] = len(episode)
    if episode.seed is not None:
        demo.attrs["seed"] = episode.seed
        demo.attrs["options"] = json.dumps(episode.options)
    if episode.metadata is not None:
        demo.attrs["metadata"] = json.dumps(episode.metadata)
