"""Exit 1 unless a run's replay succeeded (``report.json``: ``replay.success``), for
``make test-lowest``: a run on the lowest supported versions must do its task, not only finish.

    python scripts/ci/check_outcome.py RUN_DIR

Prints one line either way: the outcome, the planned and the replayed clearance. Standard
library only (it runs in the lowest versions' venv too).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def check(run_dir: Path) -> tuple[bool, str]:
    """Whether the run at ``run_dir`` succeeded, and a line that says how it ended."""
    try:
        report = json.loads((run_dir / "report.json").read_text(encoding="utf-8"))
        replay, plan = report["replay"], report["optimization"]
        line = (
            f"{run_dir}: outcome {replay['outcome']}, success {replay['success']}, planned "
            f"clearance {plan['min_distance_m'] * 1e3:.1f} mm, replayed "
            f"{replay['min_distance_m'] * 1e3:.1f} mm"
        )
    except (OSError, ValueError, KeyError, TypeError) as error:
        return False, f"{run_dir}: no report.json with a replay outcome ({error})"
    return replay["success"] is True, line


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("usage: check_outcome.py RUN_DIR", file=sys.stderr)
        return 2
    ok, line = check(Path(argv[0]))
    print(("" if ok else "FAILED: ") + line)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
