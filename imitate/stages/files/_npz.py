"""Reading a run file: its arrays, and its conversion's errors, named with the stage to re-run."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from imitate.errors import ImitateError
from imitate.rundir.artifacts import Arrays, load_npz
from imitate.stages import table

__all__ = ["read", "reading"]


def read(run_dir: Path, name: str, required: tuple[str, ...]) -> Arrays:
    """The arrays of the run file ``name`` (:mod:`imitate.rundir.layout`) in ``run_dir``, each of
    ``required`` present.

    Raises:
        ImitateError: the file is missing, unreadable or lacks a required array; the message
            names it and the command that writes it again (:func:`imitate.stages.table.rerun`).
    """
    path = Path(run_dir) / name
    return load_npz(path, required=required, hint=table.rerun(path))


@contextmanager
def reading(path: Path) -> Iterator[None]:
    """Within the block (the arrays of ``path`` turned into objects), an ``ImitateError``,
    ``ValueError`` or ``TypeError`` becomes an ``ImitateError`` naming ``path`` and the command
    that writes it again (one that names ``path`` already, an array it lacks, passes as it
    is)."""
    try:
        yield
    except (ImitateError, ValueError, TypeError) as err:
        if str(err).startswith(str(path)):
            raise
        raise ImitateError(f"{path}: {err}; {table.rerun(path)}") from err
