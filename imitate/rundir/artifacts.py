"""Run-directory artifacts: written atomically, read back with errors that name the file.

Every file is first written to a hidden temporary name unique to the writer
(``.NAME.PID-RANDOM.partial.SUFFIX``) and then renamed, so an interrupted write never leaves a
half-written artifact behind. Inside :func:`staged` the renames wait until the whole stage has
succeeded: a stage that fails, or is interrupted, leaves the run directory as it was (Ctrl-C and
SIGTERM wait for the renames to end; a rename that fails midway names what it replaced).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import secrets
import shutil
import stat
import zipfile
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from contextvars import ContextVar
from pathlib import Path
from typing import Any

import numpy as np

from imitate.errors import ImitateError, shell_word
from imitate.rundir import signals
from imitate.rundir.layout import EXPORT, MANIFEST, OWN

__all__ = [
    "MAX_NPZ_BYTES", "Arrays", "Staging", "cut_commits", "digest", "leftovers", "load_json",
    "load_npz", "refuse_link", "remove_temporary", "save_bytes", "save_json", "save_npz", "staged",
    "write_atomic",
]

# a temporary file (_temporary): .NAME.PID-HEX8.partial.SUFFIX, SUFFIX that of NAME
_TEMPORARY = re.compile(r"\.(?P<name>.+)\.\d+-[0-9a-f]{8}\.partial(?P<suffix>(\.[^.]*)?)")
# an export's temporary folder (tempfile.mkdtemp's 8 characters)
_EXPORT_TEMPORARY = re.compile(r"\.[a-z0-9]+\.[a-z0-9_]{8}\.partial")
# The most an .npz artifact's arrays may take once read [bytes]: a run's are a few MB; a file
# that inflates beyond it (a zip bomb) is refused before its members are read.
MAX_NPZ_BYTES = 256 * 2**20


class Staging:
    """The files a stage writes under ``root``, kept under temporary names in ``root`` until
    :meth:`commit` renames them into place (see :func:`staged`); the file named ``last`` (the
    manifest, whose digests decide whether the others are the stage's) is renamed last."""

    def __init__(self, root: Path, last: str | None = None):
        self.root = Path(os.path.abspath(root))
        self.last = None if last is None else self.root / last
        self._pending: dict[Path, Path] = {}  # destination -> temporary file

    def holds(self, path: Path) -> bool:
        """Whether ``path`` lies under the root (and so waits for the commit)."""
        return Path(os.path.abspath(path)).is_relative_to(self.root)

    def write(self, path: Path, write: Callable[[Path], object]) -> None:
        """``write(tmp)`` a temporary file in the root that :meth:`commit` renames to ``path``.

        Raises:
            ImitateError: ``path`` or a folder between it and the root is a symbolic link.
        """
        path = Path(os.path.abspath(path))
        self._refuse_links(path)
        tmp = _temporary(self.root / path.name)
        try:
            write(tmp)
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        if path in self._pending:
            self._pending[path].unlink(missing_ok=True)
        self._pending[path] = tmp

    def files(self) -> dict[str, Path]:
        """The temporary file of each staged artifact, by its path relative to the root."""
        return {path.relative_to(self.root).as_posix(): tmp for path, tmp in self._pending.items()}

    def commit(self) -> None:
        """Rename every staged file into place, in the order written (``last`` last), each
        flushed to disk first and its folder after; every destination is checked before the
        first rename, and Ctrl-C and SIGTERM wait until the last (see
        :func:`imitate.rundir.signals.held`).

        Raises:
            ImitateError: a destination that cannot be written (its folder a file or a link,
                one that cannot be made or is not writable, itself a folder or a link), and
                nothing was renamed; or a rename failed, and the message names the files
                replaced and those not.
        """
        order = sorted(self._pending, key=lambda path: path == self.last)
        for path in order:
            self._refuse_links(path)
            if path.is_dir() or (path.parent.exists() and not path.parent.is_dir()):
                where = path if path.is_dir() else path.parent
                raise ImitateError(f"{where} is in the way of {path.name}: remove it")
        for folder in dict.fromkeys(path.parent for path in order):
            _writable(folder)
        for path in order:
            _flush(self._pending[path])
        with signals.held():
            for i, path in enumerate(order):
                try:
                    os.replace(self._pending[path], path)
                except OSError as err:
                    raise ImitateError(self._cut_short(order, i, err)) from err
                del self._pending[path]
            for folder in dict.fromkeys(path.parent for path in order):
                _flush(folder)

    def _cut_short(self, order: list[Path], failed: int, err: OSError) -> str:
        """The error of a commit whose rename of ``order[failed]`` raised ``err``."""
        names = [path.relative_to(self.root).as_posix() for path in order]
        return (
            f"cannot rename {names[failed]} into place in {self.root} ({err.strerror or err}); "
            f"replaced: {', '.join(names[:failed]) or 'none'}; not replaced, kept as they were: "
            f"{', '.join(names[failed:])}; run the command again"
        )

    def _refuse_links(self, path: Path) -> None:
        """Raise ``ImitateError`` if ``path`` or a folder between it and the root is a symbolic
        link (the root itself may be one: the user chose it)."""
        for part in (path, *path.parents):
            if part == self.root:
                return
            if part.is_symlink():
                raise ImitateError(
                    f"{part} is a symbolic link; imitate writes nothing through it: remove it"
                )

    def discard(self) -> None:
        """Delete the staged files not committed."""
        for tmp in self._pending.values():
            tmp.unlink(missing_ok=True)
        self._pending.clear()


_STAGING: ContextVar[Staging | None] = ContextVar("staging", default=None)


@contextmanager
def staged(root: Path, last: str | None = None) -> Iterator[Staging]:
    """Within the block, files written under ``root`` wait under temporary names; they are all
    renamed into place when the block ends normally (the one named ``last`` last), and all
    deleted when it raises."""
    staging = Staging(root, last)
    token = _STAGING.set(staging)
    try:
        yield staging
        staging.commit()
    finally:
        _STAGING.reset(token)
        staging.discard()


def write_atomic(path: Path, write: Callable[[Path], object]) -> Path:
    """Call ``write(tmp)`` for a temporary file beside ``path``, then rename it to ``path``
    (inside :func:`staged`: when the stage commits).

    Raises:
        ImitateError: inside :func:`staged`, ``path`` or a folder below the root is a symbolic
            link (nothing is written through it).
    """
    path = Path(path)
    staging = _STAGING.get()
    if staging is not None and staging.holds(path):
        staging.write(path, write)
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = _temporary(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)
    return path


def refuse_link(path: Path, root: Path | None = None) -> None:
    """Raise ``ImitateError`` if ``path`` or a folder between it and ``root`` (without
    ``root``: its own folder) is a symbolic link: a run directory's files are written and read
    where they are, never through a link to elsewhere (``root`` itself may be one: the user
    chose it)."""
    path = Path(os.path.abspath(path))
    if root is None:
        parts: tuple[Path, ...] = (path, path.parent)
    else:
        root = Path(os.path.abspath(root))
        parts = tuple(p for p in (path, *path.parents) if p.is_relative_to(root) and p != root)
    for link in parts:
        if link.is_symlink():
            raise ImitateError(
                f"{link} is a symbolic link; imitate writes nothing through it: remove it"
            )


def refuse_hard_link(path: Path) -> None:
    """Raise ``ImitateError`` if the file ``path`` (to be appended to) has another name
    elsewhere: appending would write into someone's file outside the folder."""
    if path.exists() and path.stat().st_nlink != 1:
        raise ImitateError(
            f"{path} is a hard link; imitate appends to none: remove it or give another folder"
        )


def leftovers(run_dir: Path) -> list[Path]:
    """What killed commands left in the run directory ``run_dir``: the temporary files of
    imitate's own names (:func:`_temporary` of a file of :data:`imitate.rundir.layout.OWN`, in
    the run directory and the sub-folders a stage writes) and a killed export's temporary
    folders (``export/.FORMAT.XXXXXXXX.partial``); symbolic links are not followed."""
    run_dir = Path(run_dir)
    found = []
    for folder, names in _own_names().items():
        where = run_dir / folder
        if (folder and where.is_symlink()) or not where.is_dir():  # the run directory may be one
            continue
        for path in where.iterdir():
            match = _TEMPORARY.fullmatch(path.name)
            if (match and match["name"] in names and match["suffix"] == Path(match["name"]).suffix
                    and path.is_file() and not path.is_symlink()):
                found.append(path)
    export = run_dir / EXPORT
    if export.is_dir() and not export.is_symlink():
        found += [
            p for p in export.iterdir()
            if _EXPORT_TEMPORARY.fullmatch(p.name) and p.is_dir() and not p.is_symlink()
        ]
    return sorted(found)


def remove_temporary(run_dir: Path, left: list[Path] | None = None) -> list[Path]:
    """Delete the :func:`leftovers` of the run directory ``run_dir`` (only safe while no one
    writes there: under its lock), or ``left`` of them if given; returns them."""
    left = leftovers(run_dir) if left is None else left
    for path in left:
        if path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        else:
            path.unlink(missing_ok=True)
    return left


def cut_commits(run_dir: Path, left: list[Path]) -> list[str]:
    """Of the :func:`leftovers` ``left`` in ``run_dir``, the commits cut short between their
    renames (a kill, a power cut): one line per stage, naming the files replaced and the
    command that makes the stage's files again. A staged manifest that is left names the
    stage's outputs and their digests; the commit was cut if a file in place is that output
    while the manifest in place records another."""
    run_dir = Path(run_dir)
    try:
        current = json.loads((run_dir / MANIFEST).read_text())
    except (OSError, ValueError, RecursionError):
        current = {}
    found = []
    for path in left:
        match = _TEMPORARY.fullmatch(path.name)
        if not match or match["name"] != MANIFEST:
            continue
        try:
            staged_manifest = json.loads(path.read_text())
            records = {
                name: dict(record["outputs"]) for name, record in staged_manifest.items()
            }
        except (OSError, ValueError, RecursionError, TypeError, KeyError, AttributeError):
            continue
        for stage, outputs in records.items():
            before = current.get(stage) if isinstance(current, dict) else None
            before = before.get("outputs", {}) if isinstance(before, dict) else {}
            replaced = [
                name for name, sha in outputs.items()
                if name in OWN and sha != before.get(name)
                and _sha256(run_dir / name) == sha
            ]
            if replaced:
                found.append(
                    f"{run_dir}: the commit of stage {stage} was cut short: {', '.join(replaced)} "
                    f"{'is' if len(replaced) == 1 else 'are'} new, its other files and "
                    f"{MANIFEST} as before; run `imitate {stage} {shell_word(run_dir)}` again"
                )
    return found


def check_regular(path: Path) -> None:
    """Raise ``ImitateError`` if ``path`` is there but no regular file (a FIFO, a device, a
    socket, a folder): reading a FIFO would wait for a writer, holding the run's lock. A
    missing path is left to the reader."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        return
    if not stat.S_ISREG(mode):
        raise ImitateError(
            f"{path} is not a regular file (a FIFO, device, socket or folder); imitate reads "
            "none: remove it"
        )


def save_npz(path: Path, arrays: Mapping[str, Any]) -> Path:
    """Write ``arrays`` (name -> array-like) as an uncompressed ``.npz``, atomically."""
    return write_atomic(
        # numpy's stubs read the arrays' names as its keywords (allow_pickle: bool)
        path, lambda tmp: np.savez(tmp, **{k: np.asarray(v) for k, v in arrays.items()}),  # type: ignore[arg-type]
    )


def save_bytes(path: Path, data: bytes) -> Path:
    """Write ``data`` (a PNG's bytes, say), atomically."""
    return write_atomic(path, lambda tmp: tmp.write_bytes(data))


class Arrays(dict):
    """The arrays of one ``.npz`` artifact by name; a name it lacks raises ``ImitateError``
    naming the file, followed by ``hint`` (not ``KeyError``)."""

    def __init__(self, path: Path, arrays: Mapping[str, np.ndarray], hint: str = ""):
        super().__init__(arrays)
        self.path, self.hint = Path(path), hint

    def __missing__(self, name: str) -> np.ndarray:
        raise ImitateError(_hinted(f"{self.path} lacks {name!r}", self.hint))


def load_npz(path: Path, required: tuple[str, ...] = (), hint: str = "") -> Arrays:
    """Read an ``.npz`` artifact; every array in ``required`` must be present.

    Args:
        path: The file.
        required: The arrays it must hold.
        hint: What to do about a file that is missing, corrupt or lacks an array (``"re-run
            ..."``): the end of the error's message.

    Raises:
        ImitateError: the file is missing, unreadable, or lacks a required array; the message
            names the file.
    """
    path = Path(path)
    check_regular(path)
    try:
        with zipfile.ZipFile(path) as archive:
            inflated = sum(member.file_size for member in archive.infolist())
        if inflated > MAX_NPZ_BYTES:
            raise ImitateError(_hinted(
                f"{path} holds {inflated / 2**20:.0f} MiB of arrays, more than imitate writes "
                f"(at most {MAX_NPZ_BYTES / 2**20:.0f} MiB); it is not read", hint))
        with np.load(path, allow_pickle=False) as npz:
            arrays = Arrays(path, {name: npz[name] for name in npz.files}, hint)
    except FileNotFoundError:
        raise ImitateError(_hinted(f"{path} is missing", hint)) from None
    except PermissionError as err:
        raise _unreadable(path, err) from err
    except (OSError, ValueError, zipfile.BadZipFile, EOFError, MemoryError) as err:
        raise ImitateError(_hinted(f"{path} is corrupt ({err})", hint)) from err
    missing = [name for name in required if name not in arrays]
    if missing:
        raise ImitateError(_hinted(f"{path} lacks {missing}", hint))
    return arrays


def save_json(path: Path, obj: Any) -> Path:
    """Write ``obj`` as indented JSON, atomically."""
    text = json.dumps(obj, indent=2, sort_keys=False, default=_to_builtin)
    return write_atomic(path, lambda tmp: tmp.write_text(text + "\n"))


def load_json(path: Path, hint: str = "") -> Any:
    """Read a JSON artifact, with the same errors (and ``hint``) as :func:`load_npz`."""
    path = Path(path)
    check_regular(path)
    try:
        return json.loads(path.read_text())
    except FileNotFoundError:
        raise ImitateError(_hinted(f"{path} is missing", hint)) from None
    except PermissionError as err:
        raise _unreadable(path, err) from err
    except (OSError, ValueError, RecursionError) as err:  # ValueError: bad UTF-8 too
        raise ImitateError(_hinted(f"{path} is corrupt ({err})", hint)) from err


def _hinted(message: str, hint: str) -> str:
    return f"{message}; {hint}" if hint else message


def _unreadable(path: Path, err: PermissionError) -> ImitateError:
    """A file this user may not read: not corrupt, nothing to re-run."""
    return ImitateError(
        f"{path} cannot be read by this user ({err.strerror}); give it read permission "
        f"(e.g. chmod u+r {path}) or run as its owner"
    )


def _own_names() -> dict[str, set[str]]:
    """The names of the artifacts imitate writes, by folder relative to a run directory
    (``""``: the run directory, where a stage also stages those of its sub-folders)."""
    by_folder: dict[str, set[str]] = {"": set()}
    for name in OWN:
        folder, _, base = name.rpartition("/")
        by_folder.setdefault(folder, set()).add(base)
        by_folder[""].add(base)
    return by_folder


def digest(path: Path) -> str:
    """sha256 of the file's bytes, hex (what the manifest records)."""
    check_regular(Path(path))
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def _sha256(path: Path) -> str | None:
    """:func:`digest` of a regular file, ``None`` if there is none to read."""
    try:
        return None if path.is_symlink() else digest(path)
    except (OSError, ImitateError):
        return None


def _writable(folder: Path) -> None:
    """Make ``folder`` (and its parents) if missing; raise ``ImitateError`` if that fails or
    this user cannot create files in it (before a commit's first rename)."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise ImitateError(
            f"cannot make folder {folder} ({err.strerror or err}); nothing was replaced: free "
            f"space or fix its permissions, then run the command again"
        ) from err
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ImitateError(
            f"{folder} is not writable; nothing was replaced: fix its permissions (e.g. chmod "
            f"u+w {folder}), then run the command again"
        )


def _flush(path: Path) -> None:
    """``fsync`` a file or a folder (its entries), so a rename after it survives a crash."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def _temporary(path: Path) -> Path:
    """A hidden name beside ``path`` that no other writer uses; it keeps the suffix (``np.savez``
    and ``imageio`` go by it)."""
    return path.with_name(f".{path.name}.{os.getpid()}-{secrets.token_hex(4)}.partial{path.suffix}")


def _to_builtin(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")
