"""Shared fixtures."""

from __future__ import annotations

import fcntl
import os
import shutil
import signal
import subprocess

import numpy as np
import pytest

from imitate.cli import main
from imitate.demos.synthetic import phased_demos
from imitate.learning import time_stacked
from imitate.learning.dtw import align
from imitate.stages import progress


@pytest.fixture(autouse=True)
def no_timed_progress_lines(monkeypatch):
    """No progress line comes from a stage's duration: a slow machine's stage passes
    :data:`~imitate.stages.progress.LINE_INTERVAL` where a fast one's does not, so a test that
    reads the output would depend on the machine's speed (a test of the lines sets its own)."""
    monkeypatch.setattr(progress, "LINE_INTERVAL", float("inf"))


@pytest.fixture(scope="module")
def demo_data() -> np.ndarray:
    """Aligned synthetic pouring demonstrations as (t, x) samples, shape (~2400, 8)."""
    sd = phased_demos()
    return time_stacked(list(align(sd.demos).aligned), sd.rate)


@pytest.fixture
def in_a_terminal():
    """``start(command, **popen_kwargs) -> Popen``: ``command`` in a process group of its own
    (Ctrl-C is ``os.killpg(process.pid, SIGINT)``), acting on SIGINT as in a terminal even where
    the tests run with it ignored (a non-interactive shell ignores it in what it starts in the
    background, and an ignored signal stays ignored across exec; a caught one does not)."""

    def start(command: list[str], **kwargs) -> subprocess.Popen:
        previous = signal.signal(signal.SIGINT, signal.default_int_handler)
        try:
            return subprocess.Popen(command, start_new_session=True, **kwargs)
        finally:
            signal.signal(signal.SIGINT, previous)

    return start


@pytest.fixture(scope="session")
def quick_run(tmp_path_factory):
    """A finished ``imitate run --quick`` (seed 0); copy it before changing anything in it.

    Under pytest-xdist the workers share one: the first to ask runs it, holding a lock on the
    session's directory, and the others wait for it and read it.
    """
    if "PYTEST_XDIST_WORKER" not in os.environ:
        run_dir = tmp_path_factory.mktemp("quick")
        assert main(["run", "--quick", "--out", str(run_dir)]) == 0
        return run_dir
    session = tmp_path_factory.getbasetemp().parent  # the workers' common parent
    run_dir = session / "quick"
    with open(session / "quick.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (session / "quick.done").exists():
            shutil.rmtree(run_dir, ignore_errors=True)  # a worker's failed try
            assert main(["run", "--quick", "--out", str(run_dir)]) == 0
            (session / "quick.done").touch()
    return run_dir


@pytest.fixture
def run_dir(quick_run, tmp_path):
    """A copy of the finished quick run, free to change."""
    copy = tmp_path / "run"
    shutil.copytree(quick_run, copy)
    return copy
