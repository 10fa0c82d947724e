"""The numba kernels: the warm-up's list (:data:`imitate.warmup.KERNELS`) names exactly the
modules that declare cached kernels, the Makefile reads the same list, and the warm-up's code
paths reach every kernel."""

from __future__ import annotations

import ast
import importlib
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from imitate import _numba, warmup

ROOT = Path(__file__).resolve().parents[1]
# Source folders of the package (envs/ and models/ install as imitate.envs and imitate.models).
SOURCES = {
    "imitate": ROOT / "imitate", "imitate.envs": ROOT / "envs", "imitate.models": ROOT / "models",
}


def caches(source: str) -> bool:
    """Whether the module ``source`` declares a kernel with ``@numba.njit(..., cache=True)`` (or
    ``numba.jit``, ``njit``, ``jit``)."""
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.FunctionDef):
            for decorator in node.decorator_list:
                if not isinstance(decorator, ast.Call):
                    continue
                function = decorator.func
                name = getattr(function, "attr", None) or getattr(function, "id", None)
                if name in ("njit", "jit") and any(
                    keyword.arg == "cache" and getattr(keyword.value, "value", None) is True
                    for keyword in decorator.keywords
                ):
                    return True
    return False


def cached_modules() -> set[str]:
    """The package's modules that declare cached kernels, read from their source."""
    found = set()
    for package, folder in SOURCES.items():
        for path in folder.rglob("*.py"):
            parts = path.relative_to(folder).with_suffix("").parts
            if "__pycache__" not in path.parts and caches(path.read_text()):
                found.add(".".join((package, *parts)).removesuffix(".__init__"))
    return found


def test_the_detection_reads_the_decorator():
    assert caches("import numba\n@numba.njit(cache=True, nogil=True)\ndef f(x):\n    return x\n")
    assert caches("from numba import njit\n@njit(fastmath=True, cache=True)\ndef f(x):\n    pass\n")
    assert not caches("import numba\n@numba.njit(nogil=True)\ndef f(x):\n    return x\n")
    assert not caches("import numba\n@numba.njit\ndef f(x):\n    return x\n")


def test_the_list_names_every_module_with_cached_kernels():
    assert cached_modules() == set(warmup.KERNEL_MODULES)
    assert len(warmup.KERNEL_MODULES) == len(set(warmup.KERNEL_MODULES))


@pytest.mark.skipif(shutil.which("make") is None, reason="no make")
def test_the_makefile_reads_the_list():
    # Without the flags of a make this test may run under (`make test`'s jobserver, its level):
    # the child would print its own notes among the list.
    alone = {k: v for k, v in os.environ.items() if k not in ("MAKEFLAGS", "MFLAGS", "MAKELEVEL")}
    done = subprocess.run(
        ["make", "-s", "--no-print-directory", "--eval", "kernels: ; @echo $(KERNELS)", "kernels"],
        cwd=ROOT, capture_output=True, text=True, check=True, env=alone,
    )
    files = [f"{name.replace('.', '/')}.py" for name in warmup.KERNEL_MODULES]
    assert done.stdout.split() == files


def test_the_warm_up_reaches_every_kernel(capfd):
    """Each kernel is called or reached from one called, in the warm-up's process: compiled, or
    loaded from the cache that the warm-up fills."""
    warmup.warm(processes=1)
    assert "numba: kernels ready in" in capfd.readouterr().err
    assert warmup.uncompiled(warmup.KERNEL_MODULES) == []
    for name in warmup.KERNEL_MODULES:
        assert _numba.cached(importlib.import_module(name)), name
