"""Datasets from a run: the robot's reproduction and the teacher's demonstrations as episodes
(:mod:`imitate.export.episodes`), in one of :data:`FORMATS`.

    imitate export runs/latest --format minari --out datasets/    # or hdf5, lerobot; --images
    imitate export runs/latest --format lerobot --from-eval runs/latest/eval/default-w10000-variance

The formats' libraries are the optional extra ``pip install 'imitate-humanoid[export]'``. The export
holds the run directory's lock and refuses a plan or model that no longer follows from the run
(as the ``replay`` stage would); the output is written to a temporary directory of its own
beside ``out`` and renamed when complete.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path

from imitate import defaults
from imitate.errors import ImitateError
from imitate.rundir.artifacts import refuse_link
from imitate.rundir.lock import locked
from imitate.stages import provenance, table

__all__ = ["FORMATS", "export"]

FORMATS = defaults.EXPORT_FORMATS
_NEEDS = {"minari": ("minari", "h5py"), "hdf5": ("h5py",), "lerobot": ("pyarrow",)}


def export(run_dir: str | Path, format: str, out: str | Path | None = None,
           images: bool = False, from_eval: str | Path | None = None) -> Path:
    """Write the run's episodes in ``format``; returns the output directory, absolute.

    Args:
        run_dir: The run directory; needs ``config.json``, ``demos.npz``, ``model.npz`` and
            ``plan.npz``.
        format: One of :data:`FORMATS`: ``"minari"`` (a Minari datasets root: ``out`` is its
            ``MINARI_DATASETS_PATH``), ``"hdf5"`` (robomimic-style ``robot.hdf5`` and
            ``teacher.hdf5``) or ``"lerobot"`` (LeRobot v3.0 datasets ``robot/``, ``teacher/``).
        out: A directory that does not exist yet; ``None``: ``run_dir/export/<format>``, but
            for ``"minari"`` Minari's datasets root (``MINARI_DATASETS_PATH``, else
            ``~/.minari/datasets``), where the two datasets must not exist yet.
        images: Also store camera images at every step, at the run's camera size: the robot's
            workspace camera in the replay (its hands and the objects they hold), the teacher's
            demonstrations as the robot's eyes saw them.
        from_eval: An evaluation's folder (``RUN_DIR/eval/...``, of this run): the robot's
            episodes are then one per evaluated variation (:mod:`imitate.export.from_eval`),
            not the run's plan; ``"hdf5"`` or ``"lerobot"`` only (a Minari dataset has one env).

    Raises:
        ImitateError: an unknown format, the format's library missing, ``out`` existing or,
            within the run directory, a symbolic link on the way to it, a missing or stale
            artifact (the message names the stage to re-run), an evaluation
            that no longer follows from its models, or another command holding the run
            directory.
    """
    if format not in FORMATS:
        raise ImitateError(f"format {format!r} unknown; accepted: {FORMATS}")
    if from_eval is not None and format == "minari":
        raise ImitateError(
            f"from_eval={str(from_eval)!r} with format='minari' not accepted: a Minari dataset "
            "has one env and the variations' scenes differ; accepted: format='hdf5' or "
            "format='lerobot'"
        )
    from imitate.run import load_run

    run = load_run(run_dir)  # a missing run first: nothing to install for it
    missing = [name for name in _NEEDS[format] if importlib.util.find_spec(name) is None]
    if missing:
        raise ImitateError(
            f"the {format} format needs {', '.join(missing)}: "
            "pip install 'imitate-humanoid[export]'"
        )
    from imitate.export.episodes import Episode, robot_episode, teacher_episodes
    from imitate.export.from_eval import evaluated, evaluated_episodes

    into_root = out is None and format == "minari"
    moved: tuple[str, ...]
    if into_root:
        from imitate.envs.task import get_task
        from imitate.export.to_minari import dataset_ids

        root = Path(os.environ.get("MINARI_DATASETS_PATH") or "~/.minari/datasets")
        out = root.expanduser().absolute()
        moved = dataset_ids(get_task(run.config.task).env_id)  # the datasets' folders
    else:
        out = (Path(out) if out is not None else run.path / "export" / format).absolute()
        moved = ("",)  # the whole folder
    write = importlib.import_module(f"imitate.export.to_{format}").write
    reading = not out.is_relative_to(run.path.absolute())  # writes nothing in the run
    with locked(run.path, f"imitate export {run.path}", reading=reading):
        problems = provenance.stale(
            run.path, table.find("replay"), run.config, provenance.load(run.path)
        )
        if problems:
            raise ImitateError(f"{problems[0]} before exporting")
        if out.is_relative_to(run.path.absolute()):  # no link between the run and its export
            refuse_link(out, run.path.absolute())
        taken = [out / name for name in moved if (out / name).exists()]
        if taken:
            raise ImitateError(f"{taken[0]} exists; accepted: a path that does not exist yet" + (
                " (minari.delete_dataset removes a dataset, or give --out)" if into_root else ""
            ))
        robot: Iterable[Episode] = [robot_episode(run, images)] if from_eval is None else (
            evaluated_episodes(run, evaluated(run, Path(from_eval)), images)
        )
        parent = out if into_root else out.parent
        parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", suffix=".partial", dir=parent))
        try:
            write(tmp, robot, teacher_episodes(run, images))
            for name in moved:
                (out / name).parent.mkdir(parents=True, exist_ok=True)
                os.replace(tmp / name, out / name)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    return out
