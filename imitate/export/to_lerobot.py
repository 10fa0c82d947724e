"""LeRobot datasets (format v3.0, what ``lerobot`` >= 0.4 reads), written with pyarrow alone:
``robot/`` and ``teacher/``.

Each dataset holds its episodes back to back in one file per kind:

- ``data/chunk-000/file-000.parquet``: one row per step: ``observation.state``,
  ``observation.environment_state`` (the episode's ``environment``: the tool's and target's
  frames; an evaluated variation's obstacle and fixtures after them), ``action``,
  ``next.reward``, ``next.done``, ``next.success`` (robot), ``timestamp`` (from the episode's
  start), ``frame_index``, ``episode_index``, ``index`` (over the dataset), ``task_index``;
- with ``--images``, ``videos/observation.images.<camera>/chunk-000/file-000.mp4`` (H.264), the
  episodes' frames back to back (the robot's: its workspace camera; the teacher's: the eyes that
  watched it);
- ``meta/info.json`` (features, fps, totals), ``meta/tasks.parquet`` (the task, the episodes'
  ``instruction``, by its index, as pandas writes it),
  ``meta/episodes/chunk-000/file-000.parquet`` (one row per episode: its rows
  ``dataset_from_index..dataset_to_index``, its span of each video
  ``from_timestamp..to_timestamp`` [s], its statistics ``stats/<feature>/<stat>`` and, where the
  episode has any, ``metadata``: JSON of what it is, e.g. an evaluated variation's settings and
  outcome), ``meta/stats.json`` (the statistics over all episodes);
- ``README.md``: the dataset card (Hugging Face's form, as LeRobot's own datasets have it):
  what was recorded, its features, its licence and the paper to cite.

A row holds the observation before the step, so an episode's last observation is not stored.
Both datasets name their features alike: ``<observation>.<component>`` (``<tool>.x``, ...), and
the teacher's actions (the next frame's objects) as its ``observation.environment_state``.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from contextlib import ExitStack, closing
from pathlib import Path
from typing import Any

import imageio.v2 as imageio
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from imitate.envs.video import ENCODER
from imitate.errors import ImitateError
from imitate.export.episodes import Episode

__all__ = ["CODEBASE_VERSION", "DATA_PATH", "EPISODES_PATH", "VIDEO_PATH", "write"]

CODEBASE_VERSION = "v3.0"
DATA_PATH = "data/chunk-{chunk_index:03d}/file-{file_index:03d}.parquet"
VIDEO_PATH = "videos/{video_key}/chunk-{chunk_index:03d}/file-{file_index:03d}.mp4"
EPISODES_PATH = "meta/episodes/chunk-000/file-000.parquet"
QUANTILES = (0.01, 0.10, 0.50, 0.90, 0.99)  # LeRobot's q01 .. q99
_FIRST = {"chunk_index": 0, "file_index": 0}  # every file here is its kind's first
_VIDEO_INFO = {
    "video.codec": "h264", "video.pix_fmt": "yuv420p", "video.is_depth_map": False,
    "has_audio": False,
}


def write(out: Path, robot: Iterable[Episode], teacher: Iterable[Episode]) -> None:
    """Write the datasets ``out/robot`` and ``out/teacher``, an episode at a time."""
    _write_dataset(out / "robot", robot, robot_type="imitate_humanoid")
    _write_dataset(out / "teacher", teacher, robot_type="imitate_teacher")


def _write_dataset(root: Path, episodes: Iterable[Episode], robot_type: str | None) -> None:
    info: dict[str, Any] = {}
    rows: list[dict[str, Any]] = []
    stats: list[dict[str, dict]] = []
    frames, instruction = 0, ""
    with ExitStack() as files:
        data, videos = None, {}
        for i, episode in enumerate(episodes):
            instruction = instruction or episode.instruction
            fps = _fps(episode, info.get("fps"))
            columns, images = _frames(episode, i, frames, fps)
            table = _table(columns)
            if data is None:
                info = _info(columns, images, episode, fps, robot_type)
                data = files.enter_context(pq.ParquetWriter(_path(root, DATA_PATH), table.schema))
                videos = {key: files.enter_context(closing(imageio.get_writer(
                    _path(root, VIDEO_PATH, video_key=key), fps=fps, macro_block_size=8,
                    **ENCODER,
                ))) for key in images}
            data.write_table(table)
            for key, frames_of_key in images.items():
                for image in frames_of_key:
                    videos[key].append_data(image)
            episode_stats = {k: _stats(v) for k, v in columns.items()}
            episode_stats.update({k: _image_stats(v) for k, v in images.items()})
            stats.append(episode_stats)
            rows.append(_row(i, episode, frames, fps, images, episode_stats))
            frames += len(episode)
    if not rows:
        raise ImitateError(f"{root.name}: no episode to write")
    n = len(rows)
    info.update(total_episodes=n, total_frames=frames, splits={"train": f"0:{n}"})
    pq.write_table(pa.Table.from_pylist(rows), _path(root, EPISODES_PATH))
    _write_tasks(root / "meta" / "tasks.parquet", instruction)
    aggregated = {key: _aggregate([s[key] for s in stats]) for key in stats[0]}
    (root / "meta" / "stats.json").write_text(json.dumps(aggregated, indent=4) + "\n")
    (root / "meta" / "info.json").write_text(json.dumps(info, indent=4) + "\n")
    (root / "README.md").write_text(_card(root.name, instruction, info))


def _card(name: str, instruction: str, info: dict) -> str:
    """The dataset card of dataset ``name`` (``robot`` or ``teacher``)."""
    who = {"robot": "the humanoid's reproductions, replayed in MuJoCo physics",
           "teacher": "the teacher's demonstrations, as the humanoid observed them"}[name]
    features = "\n".join(f"- `{key}`: {f['dtype']} {f['shape']}"
                         for key, f in info["features"].items())
    n = info["total_episodes"]
    counts = f"{n} episode{'s' * (n != 1)}, {info['total_frames']} frames at {info['fps']} fps"
    return f"""---
license: apache-2.0
task_categories:
- robotics
tags:
- LeRobot
- imitate
- imitation-learning
- mujoco
configs:
- config_name: default
  data_files: data/*/*.parquet
---

# imitate: {instruction}

{counts} of {who},
written by imitate (the Python package `imitate-humanoid`), a MuJoCo reproduction of
task-level imitation learning with variance-based movement optimization (Mühlig et al., ICRA
2009). LeRobot dataset format {CODEBASE_VERSION}; `meta/info.json` holds the features, an
episode's `metadata` (in `meta/episodes/`) what it is.

## Features

{features}

## Citation

```bibtex
@inproceedings{{muehlig2009task,
  title     = {{Task-level Imitation Learning using Variance-based Movement Optimization}},
  author    = {{M{{\"u}}hlig, Manuel and Gienger, Michael and Hellbach, Sven and Steil, Jochen J.
               and Goerick, Christian}},
  booktitle = {{IEEE International Conference on Robotics and Automation (ICRA)}},
  year      = {{2009}}
}}
```
"""


def _path(root: Path, template: str, **keys: str) -> Path:
    path = root / template.format(**_FIRST, **keys)
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def _fps(episode: Episode, dataset_fps: int | None) -> int:
    """The episode's frame rate [Hz]; LeRobot takes whole numbers only, one per dataset."""
    fps = round(1.0 / episode.dt)
    if abs(fps * episode.dt - 1.0) > 1e-9:
        raise ImitateError(
            f"LeRobot needs a whole frame rate; this episode has {1.0 / episode.dt:g} Hz (the "
            f"run's --fps for the teacher); accepted: an integer rate"
        )
    if dataset_fps is not None and fps != dataset_fps:
        raise ImitateError(f"an episode at {fps} Hz in a dataset at {dataset_fps} Hz")
    return fps


def _frames(
    episode: Episode, index: int, start: int, fps: int
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The rows of ``episode`` by feature, and its videos by feature: ``(n, ...)`` each."""
    n = len(episode)
    obs = {k: v[:-1] for k, v in episode.observations.items()}
    state, environment = _state_keys(episode)
    columns = {
        "observation.state": np.hstack([obs[k] for k in state]).astype(np.float32),
        "observation.environment_state": np.hstack([obs[k] for k in environment]).astype(
            np.float32
        ),
        "action": episode.actions.astype(np.float32),
        "next.reward": episode.rewards.astype(np.float32),
        "next.done": episode.terminations | episode.truncations,
    }
    if "is_success" in episode.infos:
        columns["next.success"] = episode.infos["is_success"][1:].astype(bool)
    frame = np.arange(n)
    columns.update({
        "timestamp": (frame / fps).astype(np.float32),
        "frame_index": frame,
        "episode_index": np.full(n, index),
        "index": start + frame,
        "task_index": np.zeros(n, dtype=np.int64),
    })
    videos = {f"observation.images.{camera}": obs[camera] for camera in episode.images}
    for key, images in videos.items():
        height, width = images.shape[1:3]
        if height % 8 or width % 8:
            raise ImitateError(
                f"{key}: LeRobot videos here need image sizes divisible by 8; the run's images "
                f"are {width}x{height} (accepted: e.g. --width 320 --height 240)"
            )
    return columns, videos


def _info(columns, videos, episode: Episode, fps: int, robot_type: str | None) -> dict:
    """``meta/info.json`` less its totals."""
    state, environment = _state_keys(episode)
    names = {
        "observation.state": [f"{k}.{n}" for k in state for n in episode.names[k]],
        "observation.environment_state": [
            f"{k}.{n}" for k in environment for n in episode.names[k]
        ],
        "action": list(episode.names["action"]),
    }
    features: dict[str, dict[str, Any]] = {}
    for key, values in columns.items():
        shape = list(values.shape[1:]) or [1]
        features[key] = {"dtype": str(values.dtype), "shape": shape, "names": names.get(key)}
    for key, images in videos.items():
        height, width, channels = images.shape[1:]
        features[key] = {
            "dtype": "video", "shape": [height, width, channels],
            "names": ["height", "width", "channels"],
            "info": {"video.fps": fps, "video.height": height, "video.width": width,
                     "video.channels": channels, **_VIDEO_INFO},
        }
    return {
        "codebase_version": CODEBASE_VERSION, "robot_type": robot_type, "total_episodes": 0,
        "total_frames": 0, "total_tasks": 1, "chunks_size": 1000, "data_files_size_in_mb": 100,
        "video_files_size_in_mb": 500, "fps": fps, "splits": {}, "data_path": DATA_PATH,
        "video_path": VIDEO_PATH if videos else None, "features": features,
    }


def _state_keys(episode: Episode) -> tuple[list[str], list[str]]:
    """The observations of ``observation.state`` and of ``observation.environment_state``."""
    obs = episode.observations
    environment = [k for k in episode.environment if k in obs]
    return [k for k in obs if k not in environment and k not in episode.images], environment


def _table(columns: dict[str, np.ndarray]) -> pa.Table:
    """A parquet table: scalars as values, vectors ``(n, k)`` as fixed-size lists."""
    return pa.table({
        k: pa.array(v) if v.ndim == 1
        else pa.FixedSizeListArray.from_arrays(pa.array(v.reshape(-1)), v.shape[1])
        for k, v in columns.items()
    })


def _row(
    index: int, episode: Episode, start: int, fps: int, videos: dict, stats: dict
) -> dict[str, Any]:
    """The episode's row of ``meta/episodes``: where its rows and frames are, its statistics."""
    n = len(episode)
    row: dict[str, Any] = {
        "episode_index": index, "tasks": [episode.instruction], "length": n,
        "data/chunk_index": 0, "data/file_index": 0,
        "dataset_from_index": start, "dataset_to_index": start + n,
        "meta/episodes/chunk_index": 0, "meta/episodes/file_index": 0,
    }
    for key in videos:
        row.update({
            f"videos/{key}/chunk_index": 0, f"videos/{key}/file_index": 0,
            f"videos/{key}/from_timestamp": start / fps,
            f"videos/{key}/to_timestamp": (start + n) / fps,
        })
    if episode.metadata is not None:
        row["metadata"] = json.dumps(episode.metadata)
    row.update({
        f"stats/{key}/{name}": value for key, s in stats.items() for name, value in s.items()
    })
    return row


def _write_tasks(path: Path, task: str) -> None:
    """``meta/tasks.parquet`` as pandas writes a frame indexed by the ``task`` (LeRobot reads
    it with pandas; without the index metadata a task would read as its number)."""
    index = "__index_level_0__"
    pandas = {
        "index_columns": [index], "column_indexes": [], "pandas_version": "2.2.0",
        "columns": [
            {"name": "task_index", "field_name": "task_index", "pandas_type": "int64",
             "numpy_type": "int64", "metadata": None},
            {"name": None, "field_name": index, "pandas_type": "unicode",
             "numpy_type": "object", "metadata": None},
        ],
    }
    table = pa.table({"task_index": pa.array([0], pa.int64()), index: pa.array([task])})
    pq.write_table(table.replace_schema_metadata({b"pandas": json.dumps(pandas).encode()}), path)


def _stats(values: np.ndarray) -> dict:
    """LeRobot's statistics of a column: min, max, mean, std, q01..q99 ``(k,)``, count."""
    axis_values = values.reshape(len(values), -1).astype(np.float64)
    return _summary(axis_values, len(values), lambda v: v.tolist())


def _image_stats(images: np.ndarray) -> dict:
    """LeRobot's statistics of a video: per channel ``(3, 1, 1)``, scaled to 0..1, estimated as
    LeRobot does from at most 100 frames, thinned to under 300 px."""
    frames = images[np.linspace(0, len(images) - 1, min(len(images), 100)).round().astype(int)]
    side = max(images.shape[1:3])
    step = side // 150 if side >= 300 else 1
    pixels = frames[:, ::step, ::step].reshape(-1, images.shape[-1]) / 255.0
    return _summary(pixels, len(images), lambda v: v.reshape(-1, 1, 1).tolist())


def _summary(values: np.ndarray, count: int, shaped) -> dict:
    """min, max, mean, std and the quantiles of ``values`` ``(samples, k)`` over the samples,
    each as ``shaped`` lays it out, and ``count``."""
    summary = {
        "min": values.min(axis=0), "max": values.max(axis=0),
        "mean": values.mean(axis=0), "std": values.std(axis=0),
        **{f"q{round(q * 100):02d}": np.quantile(values, q, axis=0) for q in QUANTILES},
    }
    return {**{k: shaped(v) for k, v in summary.items()}, "count": [count]}


def _aggregate(stats: list[dict]) -> dict:
    """One feature's statistics over episodes, as LeRobot aggregates them: extremes of the
    extremes, means weighted by count, pooled std, quantiles weighted by count."""
    counts = np.array([s["count"][0] for s in stats], dtype=float)
    weights = (counts / counts.sum()).reshape(-1, *[1] * np.ndim(stats[0]["mean"]))

    def stacked(name: str) -> np.ndarray:
        return np.array([s[name] for s in stats])

    mean = (stacked("mean") * weights).sum(axis=0)
    variance = ((stacked("std") ** 2 + (stacked("mean") - mean) ** 2) * weights).sum(axis=0)
    quantiles = {
        f"q{round(q * 100):02d}": (stacked(f"q{round(q * 100):02d}") * weights).sum(axis=0)
        for q in QUANTILES
    }
    aggregated = {
        "min": stacked("min").min(axis=0), "max": stacked("max").max(axis=0), "mean": mean,
        "std": np.sqrt(variance), **quantiles,
    }
    return {**{k: v.tolist() for k, v in aggregated.items()}, "count": [int(counts.sum())]}
