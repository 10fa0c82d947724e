"""The package as a user installs it: the wheel built from the clone, installed into a fresh
virtual environment, used from another folder (the command, ``python -m imitate``, the Gymnasium
one-liner, a quick run); one top-level name; the install hints name our distribution.

The fresh environment gets the wheel itself (``--no-deps``); its dependencies come from the
environment running the tests, through a ``.pth`` file that adds that environment's
site-packages after the new one's (no network needed, and the editable install there stays
inactive: its finder is started by a ``.pth`` file of its own, which an added path does not run).
``IMITATE_WHEEL_DEPENDENCIES=index`` installs them from the package index instead (a release
check: ``pip`` resolves the wheel's own requirements).
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

import pytest

import imitate
from imitate.stages.provenance import code_digest

ROOT = Path(__file__).resolve().parents[1]
DISTRIBUTION = "imitate-humanoid"  # pyproject.toml's [project] name; the import name is imitate
WHEEL_STEM = f"{DISTRIBUTION.replace('-', '_')}-{imitate.__version__}"
ONE_LINER = (
    "import gymnasium as gym; "
    "env = gym.make('imitate:imitate/Pouring-v0', width=64, height=48, particles=5); "
    "env.reset(seed=0); print(type(env.unwrapped).__module__)"
)
# What setuptools prints that is no warning about the package (PYTHONDONTWRITEBYTECODE).
HARMLESS = re.compile(r"byte-compiling is disabled")


def _build(tmp: Path) -> tuple[Path, str, str]:
    """The wheel of a copy of the clone (no build isolation: no network), the build's output,
    and the clone's code digest as copied."""
    source = tmp / "src"
    shutil.copytree(
        ROOT, source,
        ignore=shutil.ignore_patterns(".*", "runs", "build", "dist", "*.egg-info", "__pycache__"),
    )
    digest = code_digest()
    result = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", str(source), "--no-deps", "--no-build-isolation",
         "--verbose", "-w", str(tmp / "dist")],
        capture_output=True, text=True, check=False,
    )
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    (wheel,) = (tmp / "dist").glob("*.whl")
    return wheel, result.stdout + result.stderr, digest


def _venv(tmp: Path, wheel: Path) -> Path:
    """A fresh virtual environment (of the base interpreter, no system site-packages) with the
    wheel installed; its bin/ folder."""
    venv = tmp / "venv"
    base = getattr(sys, "_base_executable", sys.executable)
    subprocess.run([base, "-m", "venv", "--without-pip", str(venv)], check=True)
    python = venv / "bin" / "python"
    purelib = subprocess.run(
        [python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
        capture_output=True, text=True, check=True,
    ).stdout.strip()
    pip = [sys.executable, "-m", "pip", "--python", str(python), "install", "--quiet"]
    if os.environ.get("IMITATE_WHEEL_DEPENDENCIES") == "index":
        subprocess.run([*pip, str(wheel)], check=True)
    else:
        here = sysconfig.get_paths()["purelib"]  # this environment's packages, after the wheel
        (Path(purelib) / "_imitate_test_dependencies.pth").write_text(here + "\n")
        subprocess.run([*pip, "--no-deps", str(wheel)], check=True)
    return venv / "bin"


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """``(wheel, build output, bin/ of the venv with it installed, a folder outside the clone,
    an environment for commands there, the clone's code digest)``."""
    tmp = tmp_path_factory.mktemp("wheel")
    wheel, output, digest = _build(tmp)
    bin_dir = _venv(tmp, wheel)
    elsewhere = tmp / "elsewhere"
    elsewhere.mkdir()
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "VIRTUAL_ENV")}
    env["PATH"] = f"{bin_dir}{os.pathsep}{env.get('PATH', '')}"
    return wheel, output, bin_dir, elsewhere, env, digest


def _run(installed, *command: str, timeout: float = 120) -> str:
    _, _, bin_dir, elsewhere, env, _ = installed
    result = subprocess.run(
        [str(bin_dir / command[0]), *command[1:]], cwd=elsewhere, env=env,
        capture_output=True, text=True, check=False, timeout=timeout,
    )
    assert result.returncode == 0, f"{' '.join(command)}:\n{result.stdout}\n{result.stderr}"
    return result.stdout


def test_wheel_ships_every_package_and_one_top_level_name(installed):
    wheel, *_ = installed
    assert wheel.name == f"{WHEEL_STEM}-py3-none-any.whl"
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
    assert {name.split("/")[0] for name in names} == {"imitate", f"{WHEEL_STEM}.dist-info"}
    # Every source and data file of the package's folders (imitate/, and envs/ and models/ as
    # imitate.envs and imitate.models), so that a new sub-package cannot be left out.
    folders = {"imitate": "imitate", "envs": "imitate/envs", "models": "imitate/models"}
    expected = {
        f"{folders[folder]}/{path.relative_to(ROOT / folder).as_posix()}"
        for folder in folders
        for path in (ROOT / folder).rglob("*")
        if path.suffix in (".py", ".toml", ".xml", ".typed") and "__pycache__" not in path.parts
    }
    assert not expected - names, f"missing from the wheel: {sorted(expected - names)}"
    for shipped in ("imitate/cli/__init__.py", "imitate/cli/console.py", "imitate/py.typed",
                    "imitate/envs/pour/suites/effort.toml", "imitate/models/humanoid.xml",
                    f"{WHEEL_STEM}.dist-info/licenses/LICENSE"):
        assert shipped in names


def test_build_prints_no_warnings(installed):
    _, output, *_ = installed
    warnings = [line for line in output.splitlines()
                if "warning" in line.lower() and not HARMLESS.search(line)]
    assert not warnings, "\n".join(warnings)


def test_installed_command_from_another_folder(installed):
    _, _, bin_dir, *_ = installed
    where = _run(installed, "python", "-c", "import imitate; print(imitate.__file__)")
    assert Path(where.strip()).is_relative_to(bin_dir.parent), where  # the wheel's, not the clone's
    assert "usage: imitate" in _run(installed, "imitate", "--help")
    assert "usage: imitate" in _run(installed, "python", "-m", "imitate", "--help")
    assert _run(installed, "imitate", "--version") == f"imitate {imitate.__version__}\n"
    assert _run(installed, "python", "-c", ONE_LINER).strip() == "imitate.envs.pour.env"


def test_installed_code_digest_is_the_clones(installed):
    """Records made with an editable install hold for a wheel of the same files."""
    script = "from imitate.stages.provenance import code_digest; print(code_digest())"
    assert _run(installed, "python", "-c", script).strip() == installed[-1]


def test_installed_quick_run_from_another_folder(installed, quick_run):
    """The wheel's run, numba's kernels compiled afresh, gives the clone's numbers."""
    _, _, _, elsewhere, *_ = installed
    _run(installed, "imitate", "run", "--quick", "--out", "quick", timeout=900)
    report = json.loads((elsewhere / "quick" / "report.json").read_text())
    assert report["replay"]["success"] is True, report["replay"]
    clone = json.loads((quick_run / "report.json").read_text())
    for stage in ("optimization", "replay"):
        assert report[stage]["min_distance_m"] == clone[stage]["min_distance_m"]


def test_gym_make_needs_no_import_and_ignores_local_folders(tmp_path):
    for name in ("envs", "models"):  # a user's own folders of these common names
        (tmp_path / name).mkdir()
        (tmp_path / name / "__init__.py").write_text("raise ImportError('the wrong one')\n")
    result = subprocess.run(
        [sys.executable, "-c", ONE_LINER], cwd=tmp_path, capture_output=True, text=True,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.strip() == "imitate.envs.pour.env"


def _installs_of_imitate(text: str) -> list[int]:
    """The lines of ``text`` where a ``pip install`` names the distribution ``imitate`` (which
    on the package index is another project); a hint may wrap onto the next line."""
    found = []
    for m in re.finditer(r"pip install", text):
        what = re.sub(r"[\s'\"`]+", "", text[m.end():m.end() + 60])  # quotes, breaks dropped
        if re.match(r"imitate(?![\w-])", what):
            found.append(text.count("\n", 0, m.start()) + 1)
    return found


def test_install_hints_name_our_distribution():
    assert _installs_of_imitate("(pip install \"\n    \"'imitate[export]')") == [1]
    assert not _installs_of_imitate(f"pip install '{DISTRIBUTION}[export]'; pip install -e .")
    files = [ROOT / "README.md", ROOT / "CONTRIBUTING.md", ROOT / "Makefile"]
    for folder in ("imitate", "envs", "models", "scripts", "tests"):
        files += [p for p in (ROOT / folder).rglob("*") if p.suffix in (".py", ".md", ".sh")]
    found = [
        f"{path.relative_to(ROOT)}:{n}"
        for path in files if path.is_file()
        for n in _installs_of_imitate(path.read_text(encoding="utf-8"))
    ]
    assert not found, f"install hints that name PyPI's other 'imitate', not {DISTRIBUTION}: {found}"


def test_lowest_versions_check_fails_a_failed_task(tmp_path):
    """make test-lowest ends with scripts/ci/check_outcome.py: a quick run that finishes but
    fails its task fails the check."""
    check = ROOT / "scripts" / "ci" / "check_outcome.py"
    for success, status in ((False, 1), (True, 0)):
        report = {"optimization": {"min_distance_m": -0.0062},
                  "replay": {"outcome": "success" if success else "plan_collision",
                             "success": success, "min_distance_m": -0.0056}}
        (tmp_path / "report.json").write_text(json.dumps(report))
        result = subprocess.run([sys.executable, str(check), str(tmp_path)],
                                capture_output=True, text=True, check=False)
        assert result.returncode == status, result.stdout + result.stderr
        assert ("FAILED" in result.stdout) is not success
    (tmp_path / "report.json").unlink()
    assert subprocess.run([sys.executable, str(check), str(tmp_path)], check=False,
                          capture_output=True).returncode == 1


def test_lint_checks_the_projects_files_only(tmp_path):
    """make lint's `ruff check .` (pyproject.toml's include): a user's scratch scripts in the
    clone are not linted; the package's files are."""
    shutil.copy(ROOT / "pyproject.toml", tmp_path)
    for name in ("try/scratch.py", "scratch.py", "imitate/new.py", "tests/test_new.py"):
        (tmp_path / name).parent.mkdir(exist_ok=True)
        (tmp_path / name).write_text("import os\n")
    result = subprocess.run([sys.executable, "-m", "ruff", "check", ".", "--show-files"],
                            cwd=tmp_path, capture_output=True, text=True, check=True)
    listed = {Path(line).relative_to(tmp_path).as_posix()
              for line in result.stdout.splitlines() if line.startswith(str(tmp_path))}
    assert listed == {"pyproject.toml", "imitate/new.py", "tests/test_new.py"}, result.stdout


def test_citation_names_this_version():
    versions = re.findall(r"^version: (\S+)$", (ROOT / "CITATION.cff").read_text(), re.M)
    assert versions == [imitate.__version__]
