"""An exported ``--from-eval`` robot dataset read back and every episode's actions replayed in its
variation's physics: do they pour (do the task) as the dataset says?

Usage: ``python scripts/experiments/replay_dataset.py PATH`` where PATH is the ``robot.hdf5`` of
``imitate export RUN_DIR --format hdf5 --from-eval EVAL_DIR`` (read with h5py) or the ``robot/``
folder of ``--format lerobot`` (read with pyarrow as LeRobot v3.0 lays it out; its actions are
float32, the env's float64).

Prints one line per episode (teacher, variation, the evaluation's outcome, the recorded score and
the replayed one, whether each succeeded: the env's ``is_success``) and how many replay to the
recorded score exactly and to the same ``is_success``. The score is the measure the episode's
task judges success by (pour: the pour fraction, and ``poured`` its success); the columns are
headed by the first episode's task.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from imitate.envs.task import Task, get_task
from imitate.export.from_eval import replayed


def hdf5_episodes(path: Path) -> list[tuple[dict, np.ndarray]]:
    import h5py

    with h5py.File(path, "r") as f:
        demos = [f["data"][f"demo_{i}"] for i in range(len(f["data"]))]
        return [(json.loads(d.attrs["metadata"]), d["actions"][()]) for d in demos]


def lerobot_episodes(root: Path) -> list[tuple[dict, np.ndarray]]:
    import pyarrow.parquet as pq

    info = json.loads((root / "meta" / "info.json").read_text())
    episodes = pq.read_table(root / "meta/episodes/chunk-000/file-000.parquet").to_pylist()
    data = pq.read_table(root / info["data_path"].format(chunk_index=0, file_index=0))
    actions = np.array(data["action"].to_pylist(), dtype=np.float32)
    return [
        (json.loads(e["metadata"]), actions[e["dataset_from_index"]:e["dataset_to_index"]])
        for e in episodes
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("path", type=Path)
    path = parser.parse_args().path
    if not path.exists():
        sys.exit(f"replay_dataset.py: {path} does not exist")
    episodes = hdf5_episodes(path) if path.suffix == ".hdf5" else lerobot_episodes(path)
    print(f"{len(episodes)} episodes in {path}")
    if not episodes:
        return
    first, _ = episodes[0]
    task = get_task(first["task"])
    score, flag = task.score.name, _flag(task, first)
    print(f"{'teacher':>7} {'id':>4}  {'evaluated':<15}{score[:7]:>7}{'replayed':>10}  "
          f"{flag + ' ':<7}replayed")
    same_score = same_flag = 0
    for metadata, actions in episodes:
        task = get_task(metadata["task"])
        measure, key = task.score.measure, _flag(task, metadata)
        again = replayed(metadata, actions)
        success = bool(again["is_success"])
        same_score += again[measure] == metadata[measure]
        same_flag += success == metadata[key]
        print(f"{metadata['teacher']:>7} {metadata['variation']:>4}  {metadata['outcome']:<15}"
              f"{metadata[measure]:7.3f}{again[measure]:10.3f}  "
              f"{metadata[key]!s:<7}{success}")
    print(f"replayed to the recorded {score} exactly: {same_score}/{len(episodes)}; to the "
          f"recorded {flag} (is_success): {same_flag}/{len(episodes)}")


def _flag(task: Task, metadata: dict) -> str:
    """The key of ``metadata`` (an episode's, of ``task``) that says whether it succeeded: the
    one boolean of the task's part of it (``Task.exported``'s; pour: ``poured``), made here
    from the metadata itself (it holds what ``exported`` reads of the record and the info)."""
    part = task.exported(metadata, {**metadata, "is_success": True})
    return next(key for key, value in part.items() if isinstance(value, bool))


if __name__ == "__main__":
    main()
