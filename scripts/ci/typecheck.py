"""Type-check the package ``imitate`` with mypy, as it is installed.

    python scripts/ci/typecheck.py

``envs/`` and ``models/`` install as ``imitate.envs`` and ``imitate.models`` (setuptools'
``package-dir``), and an editable install reaches them through setuptools' import finder; mypy
follows neither. So the installed layout is rebuilt as symlinks in a temporary directory
(``imitate/<each entry of imitate/>``, ``imitate/envs -> envs/``, ``imitate/models -> models/``)
and mypy runs there, with the ``[tool.mypy]`` settings of ``pyproject.toml``. Its output is
printed and its exit status returned; paths under ``imitate/envs/`` and ``imitate/models/`` are
shown as the repository's ``envs/`` and ``models/``.
"""

from __future__ import annotations

import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MAPPED = {"envs": ROOT / "envs", "models": ROOT / "models"}  # package-dir of pyproject.toml


def main() -> int:
    with tempfile.TemporaryDirectory(prefix="imitate-typecheck-") as tmp:
        package = Path(tmp) / "imitate"
        package.mkdir()
        for entry in (ROOT / "imitate").iterdir():
            if entry.name != "__pycache__":
                (package / entry.name).symlink_to(entry)
        for name, source in MAPPED.items():
            (package / name).symlink_to(source, target_is_directory=True)
        result = subprocess.run(
            [sys.executable, "-m", "mypy", "--config-file", str(ROOT / "pyproject.toml"),
             "--cache-dir", str(ROOT / ".mypy_cache"),
             "-p", "imitate"],
            cwd=tmp, capture_output=True, text=True, check=False,
        )
    output = result.stdout
    for name in MAPPED:
        output = output.replace(f"imitate/{name}/", f"{name}/")
    print(output, end="")
    print(result.stderr, end="", file=sys.stderr)
    return result.returncode


if __name__ == "__main__":
    sys.exit(main())
