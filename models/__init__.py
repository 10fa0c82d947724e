"""Model definitions: MJCF files, the procedural bottle and glass, and the element names of each.

Installed as ``imitate.models``; imports nothing from the rest of ``imitate``.
"""

from __future__ import annotations

from pathlib import Path

MODELS_DIR = Path(__file__).resolve().parent


def model_path(name: str) -> Path:
    """Path of the MJCF file ``name`` (e.g. ``"humanoid.xml"``) shipped in this package.

    Raises:
        FileNotFoundError: no such file; the message lists the available ones.
    """
    path = MODELS_DIR / name
    if not path.is_file():
        available = sorted(p.name for p in MODELS_DIR.glob("*.xml"))
        raise FileNotFoundError(
            f"model file {name!r} not found in {MODELS_DIR}; available: {available}"
        )
    return path
