"""Compare two run directories: every array of every ``.npz`` and the report's numbers.

    python scripts/experiments/compare_runs.py runs/before runs/after

Prints one row per array and per report value that differs (with the largest absolute
difference), then a verdict; exits 1 when anything differs. Timings and rates (``seconds``,
``*_per_s``, ``timings``) are machine-dependent and skipped.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

SKIPPED_KEYS = ("timings", "seconds", "artifacts")


def flatten(value, prefix: str = "") -> dict[str, object]:
    """``{"a.b.0": leaf}`` for nested dicts and lists, machine-dependent keys left out."""
    if isinstance(value, dict):
        items = value.items()
    elif isinstance(value, list):
        items = enumerate(value)
    else:
        return {prefix: value}
    flat = {}
    for raw_key, item in items:
        key = str(raw_key)
        if key in SKIPPED_KEYS or key.endswith("_per_s"):
            continue
        flat.update(flatten(item, f"{prefix}.{key}" if prefix else key))
    return flat


def array_difference(a: np.ndarray, b: np.ndarray) -> str | None:
    """``None`` when equal (NaNs equal), else a short description of the difference."""
    if a.shape != b.shape or a.dtype.kind != b.dtype.kind:
        return f"shape/dtype {a.shape} {a.dtype} vs {b.shape} {b.dtype}"
    if a.dtype.kind in "fc":
        if np.array_equal(a, b, equal_nan=True):
            return None
        with np.errstate(invalid="ignore"):
            return f"max |diff| {np.nanmax(np.abs(a - b)):.3g}"
    return None if np.array_equal(a, b) else "values differ"


def compare(first: Path, second: Path) -> list[tuple[str, str]]:
    """Rows ``(what, difference)`` for everything that differs between the two runs."""
    rows = []
    names = sorted({p.name for d in (first, second) for p in d.glob("*.npz")})
    for name in names:
        if not (first / name).exists() or not (second / name).exists():
            rows.append((name, "only in one run"))
            continue
        with np.load(first / name) as a, np.load(second / name) as b:
            for key in sorted(set(a.files) | set(b.files)):
                if key not in a.files or key not in b.files:
                    rows.append((f"{name}:{key}", "only in one run"))
                elif (diff := array_difference(a[key], b[key])) is not None:
                    rows.append((f"{name}:{key}", diff))
    reports = [flatten(json.loads((d / "report.json").read_text())) for d in (first, second)]
    for key in sorted(set(reports[0]) | set(reports[1])):
        values = [r.get(key, "(absent)") for r in reports]
        if values[0] != values[1]:
            rows.append((f"report.json:{key}", f"{values[0]!r} vs {values[1]!r}"))
    return rows


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("first", type=Path)
    parser.add_argument("second", type=Path)
    args = parser.parse_args()
    rows = compare(args.first, args.second)
    for what, diff in rows:
        print(f"{what:<48} {diff}")
    n_arrays = 0
    for path in args.first.glob("*.npz"):
        with np.load(path) as arrays:
            n_arrays += len(arrays.files)
    verdict = "identical" if not rows else f"{len(rows)} differences"
    print(f"{args.first} vs {args.second}: {n_arrays} arrays and the report compared: {verdict}")
    return 0 if not rows else 1


if __name__ == "__main__":
    sys.exit(main())
