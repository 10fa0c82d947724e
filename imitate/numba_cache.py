"""numba's on-disk cache of the compiled kernels (:data:`KERNEL_MODULES`).

numba compiles a kernel at its first call and caches it on disk: in ``NUMBA_CACHE_DIR`` if set,
else in the ``__pycache__`` beside the module, else in the user's cache (``~/.cache/numba``).
Where none of them is writable (a read-only install and home), numba refuses to import a
module with cached kernels; each kernel module therefore calls :func:`ensure_writable` before
declaring them, which then moves the cache to a private directory in the temporary folder and
says so (one INFO line). The ``imitate`` command prints :func:`compile_notice` before a stage;
elsewhere (the Python API), the first compile of a kernel in a process says so in one line (see
:func:`announce_first_compile`), so that a first call that compiles for a minute is not silent.
"""

from __future__ import annotations

import functools
import hashlib
import importlib
import logging
import os
import sys
import tempfile
from pathlib import Path

from imitate.errors import ImitateError

log = logging.getLogger(__name__)

PACKAGE = Path(__file__).parent
# The one list of numba-compiled kernel modules: by the stage that first compiles them, with
# about how long that takes on the 2-core CI machine [s] (`python scripts/bench/bench_run.py`). Each
# calls ensure_writable() before declaring its kernels; the warm-up compiles them all and the
# Makefile's warm-up stamp depends on their files.
STAGE_KERNELS = {
    "observe": (("imitate.perception._rim", "imitate.perception._outline"), 4),
    "learn": (
        ("imitate.learning.dtw", "imitate.learning.kmeans", "imitate.learning._em",
         "imitate.learning.bic"),
        7,
    ),
    "optimize": (("imitate.motion._planner",), 10),
}
KERNEL_MODULES = tuple(name for names, _ in STAGE_KERNELS.values() for name in names)


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
def ensure_writable() -> None:
    """Set ``NUMBA_CACHE_DIR`` to a private temporary directory if numba has nowhere to cache
    the kernels (see the module docstring); call before ``@numba.njit(cache=True)``.

    Raises:
        ImitateError: that directory cannot be used either.
    """
    announce_first_compile()
    sources = [Path(PACKAGE, *name.split(".")[1:]).with_suffix(".py") for name in KERNEL_MODULES]
    if all(cache_dir(source) for source in sources):
        return
    fallback = Path(tempfile.gettempdir(), f"imitate-numba-{os.getuid()}")
    if not _private(fallback):
        raise ImitateError(
            f"numba cannot cache the compiled kernels: neither {sources[0].parent}, the user's "
            f"cache nor {fallback} is writable; set NUMBA_CACHE_DIR to a writable directory"
        )
    os.environ["NUMBA_CACHE_DIR"] = str(fallback)
    import numba

    # numba read the environment when imported; its config sets this attribute through
    # globals(), which its type annotations do not show.
    numba.config.CACHE_DIR = str(fallback)  # type: ignore[attr-defined]
    log.info("the kernels' default cache is not writable; numba caches them in %s", fallback)


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
            seconds = sum(s for _, s in STAGE_KERNELS.values())
            line = (
                f"numba compiles imitate's kernels on first use ({function.__module__}."
                f"{function.__qualname__} now; about {seconds} s in all, once: later processes "
                f"load them from the cache; `python -m imitate.warmup` compiles them ahead)"
            )
            if log.isEnabledFor(logging.INFO) and log.hasHandlers():
                log.info(line)
            else:
                print(line, file=sys.stderr, flush=True)

        def on_end(self, ev):
            pass

    event.register("numba:compile", FirstCompile())


def compile_notice(stage: str) -> str | None:
    """A line saying that ``stage`` compiles its kernels, else None: when numba's cache has
    no index file (``*.nbi``) for any kernel of one of its modules as declared now (the name
    holds the kernel's line)."""
    if stage not in STAGE_KERNELS:
        return None
    modules, seconds = STAGE_KERNELS[stage]
    uncached = set()
    for module in map(importlib.import_module, modules):
        assert module.__file__ is not None  # the kernel modules are source files
        where = cache_dir(Path(module.__file__))
        if where is None or not any((where / name).exists() for name in _index_names(module)):
            uncached.add(str(where))
    if not uncached:
        return None
    said()
    return (
        f"compiling the {stage} kernels once (about {seconds} s); later runs load them from "
        f"the cache at {', '.join(sorted(uncached))}"
    )


def _index_names(module) -> list[str]:
    """The names of the index files numba writes for the kernels declared in ``module``."""
    from numba.core.dispatcher import Dispatcher

    version = f"py{sys.version_info[0]}{sys.version_info[1]}{sys.abiflags}"
    names = []
    for kernel in vars(module).values():
        if isinstance(kernel, Dispatcher) and kernel.py_func.__module__ == module.__name__:
            code, qualname = kernel.py_func.__code__, kernel.py_func.__qualname__
            stem = Path(code.co_filename).stem
            names.append(f"{stem}.{qualname}-{code.co_firstlineno}.{version}.nbi")
    return names


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
