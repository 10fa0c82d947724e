"""One command at a time in a run directory: the lock ``RUN/.lock``.

The lock is an exclusive, non-blocking ``flock`` on ``RUN/.lock``, held for a whole command; the
file records its holder (pid, host, command, start) for the error a second command gets. The
kernel releases a ``flock`` when its holder exits or is killed, so a ``.lock`` left behind by a
killed process is no obstacle: the next command takes it over. Whoever holds the lock of a run
directory may also delete the temporary files that killed writers left behind (nobody else
writes there).
"""

from __future__ import annotations

import fcntl
import json
import logging
import os
import socket
import stat
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from imitate.errors import ImitateError
from imitate.rundir.artifacts import cut_commits, leftovers, remove_temporary
from imitate.rundir.layout import MANIFEST

__all__ = ["LOCK", "left_by_imitate", "locked"]

log = logging.getLogger(__name__)

LOCK = ".lock"


@contextmanager
def locked(
    run_dir: Path, command: str, create: bool = False, reading: bool = False
) -> Iterator[Path]:
    """Hold the lock of ``run_dir`` for the block, the directory made first if ``create`` (and
    removed again if the block leaves it empty). In a run directory (``manifest.json``, or the
    lock record of an ``imitate`` command) what killed commands left is deleted first
    (:func:`~imitate.rundir.artifacts.leftovers`: imitate's own temporary names only), with a
    warning for a commit they cut short; nothing in another folder. ``reading``: the block
    writes nothing in ``run_dir``, so a directory this user cannot write (read-only media, a
    shared run) is read without its lock, said in a line: no command of this user can write
    there either.

    Raises:
        ImitateError: another process holds the lock (the message names it), ``run_dir`` is
            missing (without ``create``), not a directory, or not writable, or its ``.lock`` is
            a link, hard or symbolic, no regular file, or a file of someone else's.
    """
    run_dir = Path(run_dir)
    made = _directory(run_dir, create)
    if reading and not os.access(run_dir, os.W_OK | os.X_OK):
        log.info("%s is read-only for this user: read without its lock", run_dir)
        yield run_dir
        return
    try:
        ours = (run_dir / MANIFEST).is_file() or left_by_imitate(run_dir)  # before our record
        fd = _acquire(run_dir / LOCK, command)
        try:
            if ours:
                _sweep(run_dir)
            yield run_dir
        finally:
            (run_dir / LOCK).unlink(missing_ok=True)  # still ours: unlinked before the release
            os.close(fd)
    finally:
        if made and not any(run_dir.iterdir()):
            run_dir.rmdir()


def left_by_imitate(run_dir: Path) -> bool:
    """Whether ``run_dir`` holds a lock file with the record of an ``imitate`` command: one
    that a killed command left behind, or that a running one holds."""
    path = Path(run_dir) / LOCK
    if path.is_symlink() or not path.is_file():
        return False
    try:
        with open(path, "rb") as file:
            record = _record(file.read(4096))
    except OSError:
        return False
    return record is not None and str(record["command"]).startswith("imitate ")


def _sweep(run_dir: Path) -> None:
    """Delete the leftovers of killed commands in the run directory ``run_dir``, warning of a
    commit they cut short (its staged files are the only trace of it)."""
    left = leftovers(run_dir)
    for line in cut_commits(run_dir, left):
        log.warning(line)
    remove_temporary(run_dir, left)
    if left:
        log.debug("removed %d temporary files of killed commands from %s", len(left), run_dir)


def _directory(run_dir: Path, create: bool) -> bool:
    """Checks that ``run_dir`` is a directory, making it if ``create``; whether it was made."""
    if run_dir.is_dir():
        return False
    if run_dir.exists():
        raise ImitateError(f"run directory {run_dir} is not a directory; give a directory")
    if not create:
        raise ImitateError(
            f"run directory {run_dir} does not exist; start a run with `imitate run --out "
            f"{run_dir}`"
        )
    try:
        run_dir.mkdir(parents=True)
    except OSError as err:
        raise ImitateError(f"cannot create run directory {run_dir}: {err.strerror}") from None
    return True


def _acquire(path: Path, command: str) -> int:
    """The descriptor of ``path``, locked, with the holder written into it. A symbolic link or
    anything but a regular file there is refused, not followed or written through."""
    while True:
        if path.is_symlink():
            raise ImitateError(
                f"{path} is a symbolic link; imitate follows none in a run directory: remove it"
            )
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_NOFOLLOW | os.O_NONBLOCK, 0o644)
        except OSError as err:
            raise ImitateError(
                f"cannot lock run directory {path.parent} ({err.strerror}); it must be writable"
            ) from None
        found = os.fstat(fd)
        if not stat.S_ISREG(found.st_mode):
            os.close(fd)
            raise ImitateError(f"{path} is not a regular file; remove it")
        if found.st_nlink != 1:  # a hard link to a file elsewhere: never written through
            os.close(fd)
            raise ImitateError(
                f"{path} is a hard link ({found.st_nlink} names of one file); imitate writes "
                f"through none in a run directory: remove it (rm {path})"
            )
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _holder(os.pread(fd, 4096, 0))
            os.close(fd)
            raise ImitateError(
                f"run directory {path.parent} is in use by {holder}; wait for it to end or stop "
                f"it (a killed process leaves no lock)"
            ) from None
        if _same_file(fd, path):
            break
        os.close(fd)  # its holder unlinked it between our open and flock: lock the new one
    text = os.pread(fd, 4096, 0)
    if text and _record(text) is None:  # a file of the user's that is named .lock
        os.close(fd)
        raise ImitateError(
            f"{path} holds no record of an imitate command; imitate would replace it: move it "
            f"away or give another folder"
        )
    record = {
        "pid": os.getpid(), "host": socket.gethostname(), "command": command,
        "since": time.strftime("%Y-%m-%d %H:%M:%S"),
    }
    os.ftruncate(fd, 0)
    os.pwrite(fd, json.dumps(record).encode(), 0)
    return fd


def _record(text: bytes) -> dict | None:
    """The holder record that ``text`` is (:func:`_acquire` writes it), else None."""
    try:
        record = json.loads(text)
    except (ValueError, RecursionError):
        return None
    return record if isinstance(record, dict) and {"pid", "command"} <= record.keys() else None


def _same_file(fd: int, path: Path) -> bool:
    try:
        on_disk = os.stat(path)
    except FileNotFoundError:
        return False
    held = os.fstat(fd)
    return (held.st_dev, held.st_ino) == (on_disk.st_dev, on_disk.st_ino)


def _holder(text: bytes) -> str:
    """``"pid 12 on host h (`imitate run ...`, since ...)"`` from the lock file's record."""
    try:
        h = json.loads(text)
        return f"pid {h['pid']} on host {h['host']} (`{h['command']}`, since {h['since']})"
    except (ValueError, TypeError, KeyError):
        return "another process"
