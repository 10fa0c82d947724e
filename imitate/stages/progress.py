"""Progress bars of the long stages: on a terminal, none below INFO (``imitate -q``)."""

from __future__ import annotations

import logging

log = logging.getLogger("imitate")


def bars_off() -> bool | None:
    """The ``disable`` of tqdm: progress bars on a terminal (None), none below INFO (``-q``)."""
    return None if log.isEnabledFor(logging.INFO) else True
