"""Progress of the long stages: tqdm's bars on a terminal; where stderr is not one (a log
file, a pipe), a line on the ``imitate`` logger every 10 s and at the end of a work that
took longer instead; none below INFO (``imitate -q``)."""

from __future__ import annotations

import io
import logging
import sys
import time

from tqdm import tqdm

log = logging.getLogger("imitate")

# Seconds between two progress lines where stderr is not a terminal.
LINE_INTERVAL = 10.0


def bar(iterable=None, show: bool | None = None, **kwargs) -> tqdm:
    """A progress bar over ``iterable`` (tqdm's arguments: ``total``, ``desc``, ``unit``):
    tqdm's on a terminal, elsewhere a :class:`Lines` of it; none where the ``imitate`` logger's
    level is set above INFO (``imitate -q``). ``show``:
    ``True`` tqdm's bar anywhere, ``False`` none, ``None`` as said."""
    if show is not None:
        return tqdm(iterable, disable=not show, **kwargs)
    if log.level > logging.INFO:  # set so (imitate -q); the library's callers leave it unset
        return tqdm(iterable, disable=True, **kwargs)
    if sys.stderr.isatty():
        return tqdm(iterable, **kwargs)
    return Lines(iterable, **kwargs)


class Lines(tqdm):
    """A tqdm that draws no bar: its progress as an INFO line every :data:`LINE_INTERVAL` s
    and, once it has taken that long, when it ends
    (``observe: 42% (380/905 pair) after 0:10, 0:14 left, 38.0 pair/s``)."""

    def __init__(self, iterable=None, **kwargs):
        self._start = self._last_line = time.monotonic()
        self._last_n = 0
        fmt = "{desc}: {percentage:.0f}% ({n_fmt}/{total_fmt} {unit}) after {elapsed}, "
        fmt += "{remaining} left, {rate_fmt}"
        super().__init__(
            iterable, file=io.StringIO(), disable=False, mininterval=1.0, bar_format=fmt,
            **kwargs,
        )

    def display(self, msg=None, pos=None) -> bool:
        now = time.monotonic()
        done = self.total is not None and self.n >= self.total
        done = done and now - self._start >= LINE_INTERVAL  # a short work: no line at its end
        if self.n > self._last_n and (done or now - self._last_line >= LINE_INTERVAL):
            self._last_line, self._last_n = now, self.n
            log.info(self.format_meter(**self.format_dict))
        return True
