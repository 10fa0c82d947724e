"""Print the dependencies of ``pyproject.toml`` pinned at their lower bounds, one per line
(``numpy>=1.26,<3`` -> ``numpy==1.26``), for ``make test-lowest``.

    python scripts/ci/lowest_requirements.py > requirements-lowest.txt

Every dependency must have a lower bound (``>=``); the pins install only if each bound is a
release that exists.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"


def dependencies(pyproject: str) -> list[str]:
    """The quoted requirements of ``[project] dependencies = [...]`` (Python 3.10 has no
    tomllib)."""
    block = re.search(r"^dependencies = \[(.*?)^\]", pyproject, re.MULTILINE | re.DOTALL)
    return re.findall(r'^\s*"([^"]+)"', block[1], re.MULTILINE)


def lowest(requirements: list[str]) -> list[str]:
    """``name==lower`` for each requirement ``name>=lower[,...]``."""
    pins = []
    for requirement in requirements:
        match = re.match(r"\s*([A-Za-z0-9._\-]+)\s*>=\s*([^,;\s]+)", requirement)
        if match is None:
            sys.exit(f"lowest_requirements.py: {requirement!r} has no lower bound (>=)")
        pins.append(f"{match[1]}=={match[2]}")
    return pins


if __name__ == "__main__":
    print("\n".join(lowest(dependencies(PYPROJECT.read_text()))))
