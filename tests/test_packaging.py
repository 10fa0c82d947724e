"""The installed package: one top-level name, the Gymnasium one-liner from anywhere."""

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import imitate

ROOT = Path(__file__).resolve().parents[1]
ONE_LINER = (
    "import gymnasium as gym; "
    "env = gym.make('imitate:imitate/Pouring-v0', width=64, height=48, particles=5); "
    "env.reset(seed=0); print(type(env.unwrapped).__module__)"
)


def test_wheel_installs_one_top_level_package(tmp_path):
    source = tmp_path / "src"
    shutil.copytree(
        ROOT, source,
        ignore=shutil.ignore_patterns(".*", "runs", "build", "*.egg-info", "__pycache__"),
    )
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(source), "--no-deps", "--no-build-isolation",
         "--quiet", "-w", str(tmp_path / "dist")],
        check=True, capture_output=True,
    )
    (wheel,) = (tmp_path / "dist").glob("imitate-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        names = archive.namelist()
    assert {name.split("/")[0] for name in names} == {
        "imitate", f"imitate-{imitate.__version__}.dist-info"
    }
    for shipped in ("imitate/envs/pouring.py", "imitate/models/humanoid.xml",
                    "imitate/models/scene.xml", "imitate/models/teacher.xml", "imitate/py.typed",
                    "imitate/export/to_minari.py"):
        assert shipped in names


def test_gym_make_needs_no_import_and_ignores_local_folders(tmp_path):
    for name in ("envs", "models"):  # a user's own folders of these common names
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text("raise ImportError('the wrong one')\n")
    result = subprocess.run(
        [sys.executable, "-c", ONE_LINER], cwd=tmp_path, capture_output=True, text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "imitate.envs.pouring"
