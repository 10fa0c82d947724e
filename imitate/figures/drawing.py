"""The worker process that draws a run's figures while the figures stage makes the video.

matplotlib holds the GIL: drawn in a thread, the figures would stall the video's frames. One
worker process draws them instead (:func:`imitate.figures.plots.png`). It is spawned, not forked
(the stage's process has threads: rendering, BLAS), so a script that calls the stages guards its own
code with ``if __name__ == "__main__":``. Ctrl-C is left to the stage's process, which stops the
worker (the worker starts with SIGINT blocked, and a Ctrl-C while it starts is acted on once it
has started, not lost); a worker whose process was killed exits by itself.
"""

from __future__ import annotations

import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from contextlib import contextmanager
from contextvars import ContextVar

from imitate.figures import plots

__all__ = ["ahead", "worker"]

PARENT_POLL_S = 1.0  # how often the worker checks that its parent is alive [s]

_AHEAD: ContextVar[ProcessPoolExecutor | None] = ContextVar("drawing_ahead", default=None)


@contextmanager
def ahead() -> Iterator[None]:
    """Within the block, :func:`worker` gives one worker process started now, whose imports (a
    second or two) are done while the stages before the figures run."""
    with _started() as pool:
        token = _AHEAD.set(pool)
        try:
            yield
        finally:
            _AHEAD.reset(token)


@contextmanager
def worker() -> Iterator[ProcessPoolExecutor]:
    """The worker process of the enclosing :func:`ahead`, else one started for this block."""
    pool = _AHEAD.get()
    if pool is not None:
        yield pool
        return
    with _started() as pool:
        yield pool


@contextmanager
def _started() -> Iterator[ProcessPoolExecutor]:
    """One worker process, started now, stopped when the block ends."""
    pool = ProcessPoolExecutor(
        1, mp_context=multiprocessing.get_context("spawn"), initializer=_start,
        initargs=(os.getpid(),),
    )
    try:
        with _holding_ctrl_c():  # the worker inherits SIGINT blocked
            pool.submit(int)  # starts the worker
        yield pool
    finally:
        pool.shutdown(cancel_futures=True)


def _start(parent: int) -> None:
    """The worker's initializer: Agg, and exit (at once) when process ``parent`` is no longer
    its parent (gone, perhaps before this ran)."""
    plots.use_agg()

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


@contextmanager
def _holding_ctrl_c() -> Iterator[None]:
    """SIGINT blocked in the calling thread within the block, so that a process started there
    inherits it blocked, and a Ctrl-C meanwhile held and raised again after the block (in the
    main thread only: no other may set a handler)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    held = []
    previous = signal.signal(signal.SIGINT, lambda signum, _frame: held.append(signum))
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # a pending Ctrl-C arrives: held
        signal.signal(signal.SIGINT, previous)
        if held:
            signal.raise_signal(signal.SIGINT)
