"""LeRobot datasets (format v2.1), written with pyarrow alone: ``robot/`` and ``teacher/``.

Each dataset: ``data/chunk-000/episode_NNNNNN.parquet`` (one row per step: ``observation.state``,
``observation.environment_state`` (the bottle's and glass's frames), ``action``, ``next.reward``,
``next.done``, ``next.success`` (robot), ``timestamp``, ``frame_index``, ``episode_index``,
``index``, ``task_index``), with ``--images`` ``videos/chunk-000/observation.images.<eye>/
episode_NNNNNN.mp4`` (H.264), and ``meta/info.json``, ``meta/episodes.jsonl``,
``meta/tasks.jsonl``, ``meta/episodes_stats.jsonl``. A row holds the observation before the step,
so an episode's last observation is not stored.
"""

from __future__ import annotations

import json
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from imitate.envs.observation import EYES
from imitate.envs.video import write_video
from imitate.errors import ImitateError
from imitate.export.episodes import OBJECTS, TASK, Episode

__all__ = ["CODEBASE_VERSION", "DATA_PATH", "VIDEO_PATH", "write"]

CODEBASE_VERSION = "v2.1"
CHUNKS_SIZE = 1000  # episodes per chunk
DATA_PATH = "data/chunk-{episode_chunk:03d}/episode_{episode_index:06d}.parquet"
VIDEO_PATH = "videos/chunk-{episode_chunk:03d}/{video_key}/episode_{episode_index:06d}.mp4"
_VIDEO_INFO = {
    "video.codec": "h264", "video.pix_fmt": "yuv420p", "video.is_depth_map": False,
    "has_audio": False,
}


def write(out: Path, robot: Episode, teacher: Iterable[Episode]) -> None:
    """Write the datasets ``out/robot`` and ``out/teacher``."""
    _write_dataset(out / "robot", [robot], robot_type="imitate_humanoid")
    _write_dataset(out / "teacher", teacher, robot_type=None)


def _write_dataset(root: Path, episodes: Iterable[Episode], robot_type: str | None) -> None:
    info, frames = None, 0
    for i, episode in enumerate(episodes):
        fps = _fps(episode)
        columns, videos = _frames(episode, i, frames, fps)
        if info is None:
            info = _info(columns, videos, episode, fps, robot_type)
        chunk = i // CHUNKS_SIZE
        path = root / DATA_PATH.format(episode_chunk=chunk, episode_index=i)
        path.parent.mkdir(parents=True, exist_ok=True)
        pq.write_table(pa.table({k: _arrow(v) for k, v in columns.items()}), path)
        for key, images in videos.items():
            video = root / VIDEO_PATH.format(episode_chunk=chunk, video_key=key, episode_index=i)
            write_video(video, images, fps)
        stats = {k: _stats(v) for k, v in columns.items()}
        stats.update({k: _image_stats(v) for k, v in videos.items()})
        _append(root / "meta/episodes.jsonl", {"episode_index": i, "tasks": [TASK],
                                                "length": len(episode)})
        _append(root / "meta/episodes_stats.jsonl", {"episode_index": i, "stats": stats})
        frames += len(episode)
    n = i + 1
    assert info is not None  # set at the first episode, and there was one (i is bound)
    info.update(
        total_episodes=n, total_frames=frames, total_videos=n * len(videos),
        total_chunks=-(-n // CHUNKS_SIZE), splits={"train": f"0:{n}"},
    )
    _append(root / "meta/tasks.jsonl", {"task_index": 0, "task": TASK})
    (root / "meta/info.json").write_text(json.dumps(info, indent=4) + "\n")


def _fps(episode: Episode) -> int:
    """The episode's frame rate [Hz]; LeRobot takes whole numbers only."""
    fps = round(1.0 / episode.dt)
    if abs(fps * episode.dt - 1.0) > 1e-9:
        raise ImitateError(
            f"LeRobot needs a whole frame rate; this episode has {1.0 / episode.dt:g} Hz (the "
            f"run's --fps for the teacher); accepted: an integer rate"
        )
    return fps


def _frames(
    episode: Episode, index: int, start: int, fps: int
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:
    """The rows of ``episode`` by feature, and its videos by feature: ``(n, ...)`` each."""
    n = len(episode)
    obs = {k: v[:-1] for k, v in episode.observations.items()}
    state = [k for k in obs if k not in OBJECTS and k not in EYES]
    columns = {
        "observation.state": np.hstack([obs[k] for k in state]).astype(np.float32),
        "observation.environment_state": np.hstack([obs[k] for k in OBJECTS]).astype(np.float32),
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
    videos = {f"observation.images.{eye}": obs[eye] for eye in EYES if eye in obs}
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
    obs = episode.observations
    state = [k for k in obs if k not in OBJECTS and k not in EYES]
    names = {
        "observation.state": [f"{k}.{n}" for k in state for n in episode.names[k]],
        "observation.environment_state": [f"{k}.{n}" for k in OBJECTS for n in episode.names[k]],
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
        "total_frames": 0, "total_tasks": 1, "total_videos": 0, "total_chunks": 0,
        "chunks_size": CHUNKS_SIZE, "fps": fps, "splits": {}, "data_path": DATA_PATH,
        "video_path": VIDEO_PATH if videos else None, "features": features,
    }


def _arrow(values: np.ndarray) -> pa.Array:
    """A parquet column: scalars as values, vectors ``(n, k)`` as fixed-size lists."""
    if values.ndim == 1:
        return pa.array(values)
    return pa.FixedSizeListArray.from_arrays(pa.array(values.reshape(-1)), values.shape[1])


def _stats(values: np.ndarray) -> dict:
    """LeRobot's per-episode statistics of a column: min, max, mean, std ``(k,)``, count."""
    axis_values = values.reshape(len(values), -1)
    return {
        "min": axis_values.min(axis=0).tolist(), "max": axis_values.max(axis=0).tolist(),
        "mean": axis_values.mean(axis=0).tolist(), "std": axis_values.std(axis=0).tolist(),
        "count": [len(values)],
    }


def _image_stats(images: np.ndarray) -> dict:
    """LeRobot's statistics of a video: per channel ``(3, 1, 1)``, scaled to 0..1, estimated as
    LeRobot does from at most 100 frames, thinned to under 300 px."""
    frames = images[np.linspace(0, len(images) - 1, min(len(images), 100)).round().astype(int)]
    side = max(images.shape[1:3])
    step = side // 150 if side >= 300 else 1
    pixels = frames[:, ::step, ::step].reshape(-1, images.shape[-1]) / 255.0

    def channels(v: np.ndarray) -> list:
        return v.reshape(-1, 1, 1).tolist()

    return {
        "min": channels(pixels.min(axis=0)), "max": channels(pixels.max(axis=0)),
        "mean": channels(pixels.mean(axis=0)), "std": channels(pixels.std(axis=0)),
        "count": [len(images)],
    }


def _append(path: Path, record: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a") as f:
        f.write(json.dumps(record) + "\n")
