"""Conventions of the command and the library: ``--version``, ``python -m imitate``, ``-v``/``-q``,
one-line errors for a missing OpenGL library, numba's cache where the default is not writable,
and a library import that sets nothing global.
"""

import ctypes.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import imitate
from imitate.cli import main

ROOT = Path(__file__).resolve().parents[1]


def python(code_or_args, env=None, cwd=None) -> subprocess.CompletedProcess:
    """``python -c CODE`` (a string) or ``python ARGS`` (a list) in ``cwd``, with ``env``'s
    variables set (None: unset)."""
    environ = dict(os.environ)
    for name, value in (env or {}).items():
        if value is None:
            environ.pop(name, None)
        else:
            environ[name] = value
    args = ["-c", code_or_args] if isinstance(code_or_args, str) else code_or_args
    return subprocess.run(
        [sys.executable, *args], env=environ, cwd=cwd, capture_output=True, text=True,
        check=False, timeout=300,
    )


def test_version(capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["--version"])
    assert exit_.value.code == 0
    assert capsys.readouterr().out == f"imitate {imitate.__version__}\n"


def test_python_m_imitate():
    result = python(["-m", "imitate", "--help"])
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("usage: imitate ")


@pytest.mark.parametrize("where", ["before", "after"])
def test_quiet_prints_only_the_summary(run_dir, capsys, where):
    args = ["optimize", str(run_dir), "--max-iter", "2"]
    args = ["-q", *args] if where == "before" else [*args, "-q"]
    assert main(args) == 0
    out, err = capsys.readouterr()
    assert err == ""
    assert "optimize" in out and "optimization: min_distance_m" in out


def test_quiet_keeps_warnings(run_dir, capsys):
    arrays = dict(np.load(run_dir / "model.npz"))
    arrays["mean"] = arrays["mean"] + 0.01  # another run's model
    np.savez(run_dir / "model.npz", **arrays)
    assert main(["optimize", str(run_dir), "--max-iter", "2", "--force", "-q"]) == 0
    err = capsys.readouterr().err
    assert err.startswith("warning: model.npz is not the file") and err.count("\n") == 1, err


def test_default_and_verbose(run_dir, capsys):
    assert main(["replay", str(run_dir)]) == 0
    assert capsys.readouterr().err == "== replay\n"
    assert main(["-v", "learn", str(run_dir)]) == 0  # learn: a second, not replay's four
    err = capsys.readouterr().err.splitlines()
    assert err[0].startswith(f"debug: run directory {run_dir}, settings {{")
    assert "== learn" in err and any(line.startswith("debug: learn wrote") for line in err)


def test_import_sets_nothing_and_renders_headless():
    code = """
import os
import cv2  # OpenCV adds its folder to LD_LIBRARY_PATH when first imported
import matplotlib
environ, backend = dict(os.environ), matplotlib.rcParams._get("backend")
import gymnasium as gym
import imitate, imitate.stages.runner
env = gym.make("imitate:imitate/Pouring-v0", render_mode="rgb_array", width=96, height=72,
               particles=0)
env.reset(seed=0)
assert dict(os.environ) == environ, set(os.environ.items()) ^ set(environ.items())
assert matplotlib.rcParams._get("backend") == backend
frame = env.render()
assert frame.shape == (72, 96, 3) and frame.std() > 5.0, frame.std()
"""
    result = python(code, env={"MUJOCO_GL": None})
    assert result.returncode == 0, result.stderr


UNUSABLE = {"vulkan": "MUJOCO_GL='vulkan' is not a usable backend; accepted: 'egl'"}
if ctypes.util.find_library("OSMesa") is None:
    UNUSABLE["osmesa"] = (
        "MUJOCO_GL='osmesa' but libOSMesa is not installed: install OSMesa (apt-get install "
        "libosmesa6)"
    )


@pytest.mark.parametrize("backend", sorted(UNUSABLE))
def test_no_opengl_help_works_and_rendering_fails_in_one_line(backend, tmp_path):
    result = python(["-m", "imitate", "--help"], env={"MUJOCO_GL": backend})
    assert result.returncode == 0 and result.stdout.startswith("usage: imitate "), result.stderr
    run = tmp_path / "run"
    result = python(["-m", "imitate", "observe", "--quick", "--out", str(run)],
                    env={"MUJOCO_GL": backend})
    assert result.returncode == 1
    lines = result.stderr.splitlines()
    assert lines[0] == "== observe", result.stderr
    assert lines[-1].startswith("imitate observe: error: " + UNUSABLE[backend]), result.stderr


def test_numba_cache_moves_where_the_default_is_not_writable(tmp_path):
    """The package laid out as installed, with its ``__pycache__`` folders and the home unusable
    (files where folders should be; the tests run as root, who may write anywhere): numba's
    cache moves, said in one line, and matplotlib's config moves without a warning."""
    site = tmp_path / "site"
    ignore = shutil.ignore_patterns("__pycache__")
    shutil.copytree(ROOT / "imitate", site / "imitate", ignore=ignore)
    for folder in ("envs", "models"):
        shutil.copytree(ROOT / folder, site / "imitate" / folder, ignore=ignore)
    for init in (site / "imitate").rglob("__init__.py"):
        (init.parent / "__pycache__").write_text("not a folder")
    blocked, temp = tmp_path / "blocked", tmp_path / "tmp"
    blocked.write_text("not a folder")
    temp.mkdir()
    env = {"PYTHONPATH": str(site), "HOME": str(blocked), "XDG_CACHE_HOME": str(blocked),
           "TMPDIR": str(temp), "MPLCONFIGDIR": None, "NUMBA_CACHE_DIR": None,
           "PYTHONDONTWRITEBYTECODE": "1"}
    fallback = temp / f"imitate-numba-{os.getuid()}"

    loads = ("from imitate.cli import console; console.prepare(); "
             "console.log_to_stderr(20); import imitate.perception._outline")  # as a stage
    result = python(loads, env=env, cwd=tmp_path)
    assert result.stderr.splitlines() == [
        f"the kernels' default cache is not writable; numba caches them in {fallback}"
    ], result.stderr

    code = f"""
import numpy as np
import imitate.perception._outline as outline
assert outline.__file__.startswith({str(site)!r}), outline.__file__
outline._extremes(np.zeros((3, 2)), np.zeros(2), np.array([1.0, 0.0]))
"""
    result = python(code, env=env, cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    assert list(fallback.rglob("_outline._extremes-*.nbi")), sorted(fallback.rglob("*"))
    result = python("import imitate.motion.taskspace", env=env, cwd=tmp_path)  # alone
    assert result.returncode == 0, result.stderr

