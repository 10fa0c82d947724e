"""Run a benchmark or experiment script and record what it printed in ``scripts/README.md``, under
a header with the date, the commit and the machine: its cores and the physics steps per second
of ``bench_sim``'s 60-particle scene, measured just before, so that timings taken on different
days or machines can be compared.

    python scripts/record.py scripts/bench/bench_learning.py [ARGS ...]
    python scripts/record.py -m imitate compare runs/latest --suite effort

The script's output also goes to the terminal as it comes. The section of the same command is
replaced, the others are kept; nothing is recorded when the script fails (its exit status is
this one's).
"""

from __future__ import annotations

import datetime
import importlib.util
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RECORD = ROOT / "scripts" / "README.md"
PREAMBLE = """# Measurements

What the scripts printed, one section per command, each recorded by `python scripts/record.py
COMMAND` (it replaces the section of the same command). The header of each says when, on which
commit and on which machine: `steps/s` is the physics rate of `scripts/bench/bench_sim.py`'s
60-particle scene measured just before, the machine's speed at that moment. Timings compare
across sections only as ratios to it; counts and ratios printed by one command compare as they
are.
"""


def steps_per_second() -> float:
    """Physics steps per second of the 60-particle scene over 1 s of simulated time."""
    spec = importlib.util.spec_from_file_location("bench_sim", ROOT / "scripts/bench/bench_sim.py")
    bench_sim = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench_sim)
    return bench_sim.physics_rate(60, 1.0)[0]


def commit() -> str:
    """The short commit, with ``+ changes`` if tracked files differ from it."""
    def git(*args: str) -> str:
        return subprocess.run(
            ["git", "-C", str(ROOT), *args], capture_output=True, text=True, check=True
        ).stdout.strip()

    changed = git("status", "--porcelain", "--untracked-files=no")
    return git("rev-parse", "--short", "HEAD") + (" + changes" if changed else "")


def run(command: list[str]) -> tuple[int, str]:
    """Runs ``command``, echoing its stdout; its exit status and stdout."""
    lines = []
    with subprocess.Popen(command, stdout=subprocess.PIPE, text=True, cwd=ROOT) as process:
        for line in process.stdout:
            print(line, end="", flush=True)
            lines.append(line)
    return process.returncode, "".join(lines)


def sections(text: str) -> dict[str, str]:
    """The recorded sections by their command (the ``## `...` `` heading)."""
    parts = re.split(r"^## `(.+)`\n", text, flags=re.MULTILINE)
    return {parts[i]: parts[i + 1].strip("\n") for i in range(1, len(parts) - 1, 2)}


def write(path: Path, found: dict[str, str]) -> None:
    """``path`` with the preamble and ``found``'s sections, atomically."""
    body = PREAMBLE + "".join(f"\n## `{cmd}`\n\n{text}\n" for cmd, text in found.items())
    with tempfile.NamedTemporaryFile("w", dir=path.parent, delete=False, suffix=".tmp") as f:
        f.write(body)
    os.replace(f.name, path)


def main(argv: list[str]) -> int:
    if not argv or not (argv[0].endswith(".py") or argv[:2] == ["-m", "imitate"]):
        print("usage: python scripts/record.py SCRIPT.py [ARGS ...] | -m imitate COMMAND ...",
              file=sys.stderr)
        return 2
    rate = steps_per_second()
    status, output = run([sys.executable, *argv])
    if status != 0:
        print(f"record: {argv[0]} exited with {status}; nothing recorded", file=sys.stderr)
        return status
    command = " ".join(argv[1:] if argv[0] == "-m" else ["python", *argv])
    header = (
        f"{datetime.date.today().isoformat()} · commit {commit()} · {os.cpu_count()} cores · "
        f"{rate:.0f} steps/s"
    )
    found = sections(RECORD.read_text()) if RECORD.exists() else {}
    found[command] = f"{header}\n\n```text\n{output.rstrip()}\n```"
    write(RECORD, found)
    print(f"recorded in {RECORD.relative_to(ROOT)}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
