"""Ctrl-C and SIGTERM held back while a stage's files are renamed into place.

A commit (see :meth:`imitate.rundir.artifacts.Staging.commit`) is a few renames; a signal acted
on between two of them would leave some files of the stage and some of the run before it. Within
:func:`held`, SIGINT and SIGTERM are only noted, and acted on (by the handlers that were there)
as the block ends. The handlers are swapped rather than the signals blocked: the kernel gives a
process's signal to any thread that does not block it, and Python runs the handler in the main
thread whichever thread took it, so a mask on the main thread alone would not hold it back.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager

__all__ = ["HELD", "held"]

HELD = (signal.SIGINT, signal.SIGTERM)


@contextmanager
def held() -> Iterator[None]:
    """Within the block, SIGINT and SIGTERM wait; as it ends (normally or not), each that came
    is raised again, in the order they came, for the handler that was there before (only in the
    main thread, where Python runs signal handlers; elsewhere the block runs as it is)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    came: list[int] = []
    previous = {signum: signal.signal(signum, lambda n, _: came.append(n)) for signum in HELD}
    try:
        yield
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler)
        for arrived in dict.fromkeys(came):
            signal.raise_signal(arrived)
