"""numba's on-disk cache of imitate's compiled kernels: where it lies, and one line on a first
compile.

numba compiles a kernel at its first call and caches it on disk: in ``NUMBA_CACHE_DIR`` if set,
else in the ``__pycache__`` beside the module, else in the user's cache (``~/.cache/numba``).
Where none of them is writable (a read-only install and home), numba refuses to import a
module with cached kernels; each kernel module therefore calls ``ensure_writable(__file__)``
before declaring them, which then moves the cache to a private directory in the temporary
folder and says so (one INFO line). The first compile of a kernel in a process says so in one
line (:func:`announce_first_compile`), so that a first call that compiles for a minute is not
silent, unless the caller says it its own way (:func:`said`; the warm-up and the command's
notice, ``imitate.warmup``, which holds the list of kernel modules).
"""

from __future__ import annotations

import functools
import hashlib
import logging
import os
import sys
import tempfile
from pathlib import Path
from types import ModuleType

from imitate.errors import ImitateError

log = logging.getLogger(__name__)


def cache_dir(source: Path) -> Path | None:
    """Where numba caches the kernels of the module file ``source``; None if nowhere."""
    parent = os.path.dirname(os.path.abspath(source))
    subpath = f"{os.path.basename(parent)}_{hashlib.sha1(parent.encode()).hexdigest()}"
    user = os.environ.get("XDG_CACHE_HOME", os.path.expanduser("~/.cache"))
    candidates = [Path(parent, "__pycache__"), Path(user, "numba", subpath)]
    if os.environ.get("NUMBA_CACHE_DIR"):
        candidates.insert(0, Path(os.environ["NUMBA_CACHE_DIR"], subpath))
    return next((path for path in candidates if _writable(path)), None)


@functools.cache
def ensure_writable(module_file: str) -> None:
    """Set ``NUMBA_CACHE_DIR`` to a private temporary directory if numba has nowhere to cache
    the kernels of the module file ``module_file`` (the caller's ``__file__``; see the module
    docstring); call before its ``@numba.njit(cache=True)``.

    Raises:
        ImitateError: that directory cannot be used either.
    """
    announce_first_compile()
    source = Path(module_file)
    if cache_dir(source):
        return
    fallback = Path(tempfile.gettempdir(), f"imitate-numba-{os.getuid()}")
    if not _private(fallback):
        raise ImitateError(
            f"numba cannot cache the compiled kernels: neither {source.parent}, the user's "
            f"cache nor {fallback} is writable; set NUMBA_CACHE_DIR to a writable directory"
        )
    os.environ["NUMBA_CACHE_DIR"] = str(fallback)
    import numba

    # numba read the environment when imported; its config sets this attribute through
    # globals(), which its type annotations do not show.
    numba.config.CACHE_DIR = str(fallback)  # type: ignore[attr-defined]
    log.info("the kernels' default cache is not writable; numba caches them in %s", fallback)


def kernels(module: ModuleType) -> dict:
    """The numba dispatchers that ``module`` declares, by name."""
    from numba.core.dispatcher import Dispatcher

    return {
        name: kernel for name, kernel in vars(module).items()
        if isinstance(kernel, Dispatcher) and kernel.py_func.__module__ == module.__name__
    }


def cached(module: ModuleType) -> bool:
    """Whether numba's cache holds an index file (``*.nbi``) for a kernel of ``module`` as
    declared now (the file's name holds the kernel's line)."""
    assert module.__file__ is not None  # the kernel modules are source files
    where = cache_dir(Path(module.__file__))
    version = f"py{sys.version_info[0]}{sys.version_info[1]}{sys.abiflags}"
    names = []
    for kernel in kernels(module).values():
        code, qualname = kernel.py_func.__code__, kernel.py_func.__qualname__
        names.append(f"{Path(code.co_filename).stem}.{qualname}-{code.co_firstlineno}.{version}.nbi")
    return where is not None and any((where / name).exists() for name in names)


# Whether this process has said that it compiles kernels (once is enough); a caller that says
# it its own way (the warm-up, the command's notice) sets it.
_SAID: list[bool] = []


def said() -> None:
    """No :func:`announce_first_compile` line in this process: the caller says it."""
    _SAID.append(True)


@functools.cache
def announce_first_compile() -> None:
    """When numba first starts compiling one of imitate's kernels in this process (none was in
    the cache), one line: on the ``imitate`` logger (INFO) if logging is set up for it, else on
    stderr. Registered once per process, by :func:`ensure_writable`."""
    from numba.core import event

    class FirstCompile(event.Listener):
        def on_start(self, ev):
            function = ev.data["dispatcher"].py_func
            if _SAID or not function.__module__.startswith("imitate"):
                return
            _SAID.append(True)
            line = (
                f"numba compiles imitate's kernels on first use ({function.__module__}."
                f"{function.__qualname__} now; once: later processes load them from the cache; "
                f"`python -m imitate.warmup` compiles them ahead)"
            )
            if log.isEnabledFor(logging.INFO) and log.hasHandlers():
                log.info(line)
            else:
                print(line, file=sys.stderr, flush=True)

        def on_end(self, ev):
            pass

    event.register("numba:compile", FirstCompile())


def _writable(path: Path) -> bool:
    try:
        path.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError:
        return False
    return True


def _private(path: Path) -> bool:
    """Whether ``path`` is (made) a writable directory of this user's that no one else can
    write to (the cache holds code that is loaded and run)."""
    try:
        path.mkdir(mode=0o700, exist_ok=True)
        info = path.stat()
    except OSError:
        return False
    return info.st_uid == os.getuid() and not info.st_mode & 0o022 and _writable(path)
