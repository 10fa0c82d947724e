"""Run-directory artifacts: written atomically, read back with errors that name the stage to re-run.

Every file is first written to a hidden temporary name in the same directory and then renamed,
so an interrupted stage never leaves a half-written artifact behind.
"""

from __future__ import annotations

import json
import os
import zipfile
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import numpy as np

from imitate.errors import ImitateError
from imitate.stages import producer


def write_atomic(path: Path, write: Callable[[Path], None]) -> Path:
    """Call ``write(tmp)`` for a temporary file beside ``path``, then rename it to ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.partial{path.suffix}")
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def save_npz(path: Path, arrays: Mapping[str, Any]) -> Path:
    """Write ``arrays`` (name -> array-like) as an uncompressed ``.npz``, atomically."""
    return write_atomic(
        path, lambda tmp: np.savez(tmp, **{k: np.asarray(v) for k, v in arrays.items()})
    )


def load_npz(path: Path, required: tuple[str, ...] = ()) -> dict[str, np.ndarray]:
    """Read an ``.npz`` artifact; every array in ``required`` must be present.

    Raises:
        ImitateError: the file is missing, unreadable, or lacks a required array; the message
            names the file and the stage that writes it.
    """
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as npz:
            arrays = {name: npz[name] for name in npz.files}
    except FileNotFoundError:
        raise ImitateError(f"{path} is missing; {_rerun_hint(path)}") from None
    except (OSError, ValueError, zipfile.BadZipFile, EOFError) as err:
        raise ImitateError(f"{path} is corrupt ({err}); {_rerun_hint(path)}") from err
    missing = [name for name in required if name not in arrays]
    if missing:
        raise ImitateError(f"{path} lacks {missing}; {_rerun_hint(path)}")
    return arrays


def save_json(path: Path, obj: Any) -> Path:
    """Write ``obj`` as indented JSON, atomically."""
    text = json.dumps(obj, indent=2, sort_keys=False, default=_to_builtin)
    return write_atomic(path, lambda tmp: tmp.write_text(text + "\n"))


def load_json(path: Path) -> Any:
    """Read a JSON artifact, with the same errors as :func:`load_npz`."""
    path = Path(path)
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise ImitateError(f"{path} is missing; {_rerun_hint(path)}") from None
    except (OSError, ValueError) as err:
        raise ImitateError(f"{path} is corrupt ({err}); {_rerun_hint(path)}") from err


def _rerun_hint(path: Path) -> str:
    return f"re-run `imitate {producer(path.name)} {path.parent}` to write it"


def _to_builtin(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")
