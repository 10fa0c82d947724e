"""The fast cases of ``scripts/ci/fault_injection.py`` (its ``FAST``), each on copies of the
session's quick run: kills that land mid-stage, refused commands, symbolic links. The slow ones
(the video, the commit at every rename, the evaluations) run with the script itself."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "ci" / "fault_injection.py"


def _load():
    spec = importlib.util.spec_from_file_location("fault_injection", SCRIPT)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses looks the module up
    spec.loader.exec_module(module)
    return module


faults = _load()


@pytest.mark.parametrize("name", [name for name in faults.CASES if name in faults.FAST])
def test_fast_case(name, quick_run, tmp_path):
    outcomes = faults.run_cases([name], quick_run, tmp_path)
    assert outcomes and all(o.verdict == "OK" for o in outcomes), "\n" + faults.table(outcomes)


def test_selection():
    assert faults.select(None, fast=True) == [n for n in faults.CASES if n in faults.FAST]
    assert faults.select(None, fast=False) == list(faults.CASES)
    assert faults.select("symlink-lock,kill-observe", fast=False) == [
        "kill-observe", "symlink-lock"
    ]
    with pytest.raises(ValueError, match="nope is no case; .* of kill-observe, ") as err:
        faults.select("kill-observe,nope", fast=False)
    assert "\n" not in str(err.value)
    assert len(faults.FAST) >= 5 and faults.FAST <= set(faults.CASES)
