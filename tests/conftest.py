"""Shared fixtures."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from imitate.cli import main
from imitate.dtw import align
from imitate.learning import time_stacked
from imitate.synthetic import pouring_demos


@pytest.fixture(scope="module")
def demo_data() -> np.ndarray:
    """Aligned synthetic pouring demonstrations as (t, x) samples, shape (~2400, 8)."""
    sd = pouring_demos()
    return time_stacked(list(align(sd.demos).aligned), sd.rate)



@pytest.fixture(scope="session")
def quick_run(tmp_path_factory):
    """A finished ``imitate run --quick`` (seed 0); copy it before changing anything in it."""
    run_dir = tmp_path_factory.mktemp("quick")
    assert main(["run", "--quick", "--out", str(run_dir)]) == 0
    return run_dir


@pytest.fixture
def run_dir(quick_run, tmp_path):
    """A copy of the finished quick run, free to change."""
    copy = tmp_path / "run"
    shutil.copytree(quick_run, copy)
    return copy
