"""Kill, interrupt and race ``imitate`` on copies of one quick run; print what each leaves behind.

    MUJOCO_GL=egl python scripts/ci/fault_injection.py [--base runs/quick] [--work /tmp/faults]

Without ``--base`` it first makes one (``imitate run --quick``). Every case works on a fresh
copy of it and prints one row: the exit status, what changed in the directory (against the copy
as it was just before the command), the temporary files and the lock left in it, the ffmpeg
children still running when the command had exited, and a verdict against what the README
promises (a stage that does not finish changes nothing; one line on stderr). One case is
instrumented: a wrapper around ``imitate.cli.main`` sends SIGTERM just before each rename of a
stage's commit in turn, which must wait for the whole commit. The error lines follow the table.
Takes about three minutes on two cores.
"""

from __future__ import annotations

import argparse
import fcntl
import hashlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

IMITATE = (sys.executable, "-m", "imitate")
TEMPORARY = ".*.partial*"
# imitate -q ARGS RUN_DIR, sending itself SIGTERM just before the Nth rename into RUN_DIR
SIGTERM_AT_RENAME = """
import os, signal, sys
from imitate.cli import main
n, run_dir, renames = int(sys.argv[1]), os.path.abspath(sys.argv[2]), []
replace = os.replace
def replace_and_terminate(src, dst):
    if os.path.dirname(os.path.abspath(dst)) == run_dir:
        renames.append(dst)
        if len(renames) == n:
            os.kill(os.getpid(), signal.SIGTERM)
    replace(src, dst)
os.replace = replace_and_terminate
sys.exit(main(["-q", *sys.argv[3:], run_dir]))
"""


@dataclass
class Outcome:
    """What one case did: the command's exit status and stderr, and its directory afterwards."""

    case: str
    status: int | None
    errors: list[str]
    changed: list[str]
    temporary: list[str]
    lock: str
    ffmpeg: int
    checks: dict[str, bool] = field(default_factory=dict)

    @property
    def verdict(self) -> str:
        failed = [name for name, ok in self.checks.items() if not ok]
        return "OK" if not failed else "FAIL: " + ", ".join(failed)


def snapshot(run_dir: Path) -> dict[str, str]:
    """sha256 of every file under ``run_dir`` by relative path (temporary files and the lock
    aside)."""
    return {
        p.relative_to(run_dir).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(run_dir.rglob("*"))
        if p.is_file() and not p.match(TEMPORARY) and p.name != ".lock"
    }


def changes(before: dict[str, str], after: dict[str, str]) -> list[str]:
    """``["report.json", "+new", "-gone"]``: files changed, added, removed."""
    changed = [f for f in before if f in after and before[f] != after[f]]
    return changed + [f"+{f}" for f in after if f not in before] + [
        f"-{f}" for f in before if f not in after
    ]


def lock_state(run_dir: Path) -> str:
    """``"none"``, ``"stale"`` (a file nobody holds) or ``"HELD"``."""
    path = run_dir / ".lock"
    if not path.exists():
        return "none"
    with open(path, "rb") as file:
        try:
            fcntl.flock(file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return "HELD"
    return "stale"


def ffmpeg_children(run_dir: Path) -> int:
    """Running ffmpeg processes writing into ``run_dir``."""
    count = 0
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            cmdline = (proc / "cmdline").read_bytes().decode(errors="replace")
        except OSError:
            continue
        if "ffmpeg" in cmdline and str(run_dir) in cmdline:
            count += 1
    return count


def start(*args: str) -> subprocess.Popen:
    """``imitate ARGS`` in its own process group (a terminal's Ctrl-C goes to the group)."""
    return subprocess.Popen(
        [*IMITATE, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        start_new_session=True,
    )


def wait_for_line(process: subprocess.Popen, text: str) -> list[str]:
    """Stderr lines read until one contains ``text`` (all of them if the process ends)."""
    lines = []
    for line in process.stderr:
        lines.append(line.rstrip("\n"))
        if text in line:
            break
    return lines


def wait_for_file(run_dir: Path, pattern: str, timeout: float = 120.0) -> bool:
    """Whether a file matching ``pattern`` appeared in ``run_dir`` within ``timeout`` [s]."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        if any(run_dir.glob(pattern)):
            return True
        time.sleep(0.02)
    return False


def finish(case: str, process: subprocess.Popen, run_dir: Path, before: dict[str, str],
           seen: list[str]) -> Outcome:
    """Wait for ``process``, then describe ``run_dir``."""
    rest = process.stderr.read().splitlines()
    status = process.wait()
    lines = [line for line in [*seen, *rest] if line.strip() and not line.startswith("== ")]
    folders = [run_dir, *(p for p in run_dir.iterdir() if p.is_dir())]
    return Outcome(
        case, status, lines, changes(before, snapshot(run_dir)),
        [p.name for folder in folders for p in folder.glob(TEMPORARY)],
        lock_state(run_dir), ffmpeg_children(run_dir),
    )


def one_line(outcome: Outcome, status: int) -> dict[str, bool]:
    """The checks of a command that must fail with ``status`` and one line (warnings aside),
    changing nothing."""
    errors = [line for line in outcome.errors if not line.startswith("warning: ")]
    return {
        f"exit {status}": outcome.status == status,
        "one line": len(errors) == 1 and errors[0].startswith("imitate "),
        "unchanged": not outcome.changed,
        "no lock held": outcome.lock != "HELD",
    }


def killed(case: str, base: Path, work: Path, args: list[str], wait: str, sig: int,
           group: bool = False) -> Outcome:
    """Start ``imitate ARGS`` on a copy, wait for stderr ``== stage`` (``wait``) or a file
    (``wait`` a glob), then send ``sig`` (to the process group if ``group``)."""
    run_dir = copy(base, work, case)
    before = snapshot(run_dir)
    process = start(*args, str(run_dir))
    if wait.startswith("=="):
        seen = wait_for_line(process, wait)
    else:
        seen = [] if wait_for_file(run_dir, wait) else ["(never saw " + wait + ")"]
    if group:
        os.killpg(process.pid, sig)
    else:
        os.kill(process.pid, sig)
    return finish(case, process, run_dir, before, seen)


def commit_interrupted(base: Path, work: Path, args: list[str], renames: int) -> Outcome:
    """``imitate ARGS`` on a copy of ``base`` for each of its ``renames`` renames into the run
    directory, sent SIGTERM just before that rename; each against ``imitate ARGS`` run
    untouched. One row: the status of each, what the last changed, and whether every one left
    what the untouched command did (the report and its page aside: they hold timings)."""
    reference = copy(base, work, "commit-reference")
    before = snapshot(reference)
    made = run(*args, str(reference))
    expected = snapshot(reference)
    written = changes(before, expected)
    statuses, equal, saved, last = [], True, True, None
    for n in range(1, renames + 1):
        run_dir = copy(base, work, "commit-sigterm")
        before = snapshot(run_dir)
        process = subprocess.Popen(
            [sys.executable, "-c", SIGTERM_AT_RENAME, str(n), str(run_dir), *args],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        )
        last = finish("commit-sigterm", process, run_dir, before, [])
        after = snapshot(run_dir)
        statuses.append(last.status)
        equal &= last.changed == written and all(
            after[name] == expected[name] for name in written
            if name not in ("report.json", "report.html")
        )
        saved &= len(last.errors) == 1 and "just after stage" in last.errors[0]
    last.case = f"commit-sigterm (SIGTERM before each of `{' '.join(args)}`'s {renames} renames)"
    last.status = "/".join(map(str, statuses))
    last.checks = {
        "untouched run exit 0": made.returncode == 0,
        f"exit 143 x{renames}": statuses == [143] * renames,
        "one line: the stage was saved": saved,
        "files as the untouched run's": equal,
        "no lock held": last.lock != "HELD", "no temporary files": not last.temporary,
    }
    return last


def copy(base: Path, work: Path, case: str) -> Path:
    run_dir = work / case.split()[0]
    shutil.rmtree(run_dir, ignore_errors=True)
    shutil.copytree(base, run_dir)
    return run_dir


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*IMITATE, *args], check=False, capture_output=True, text=True)


def cases(base: Path, work: Path) -> list[Outcome]:
    video = ".video.mp4.*.partial.mp4"
    outcomes = []

    o = killed("kill-observe (kill -9 in observe)", base, work, ["observe", "--quick"],
               "== observe", signal.SIGKILL)
    o.checks = {"killed": o.status == -9, "unchanged": not o.changed,
                "no lock held": o.lock != "HELD"}
    outcomes.append(o)

    o = killed("kill-learn (kill -9 in learn, --k-max 30)", base, work,
               ["learn", "--k-max", "30"], "== learn", signal.SIGKILL)
    o.checks = {"killed": o.status == -9, "unchanged": not o.changed,
                "no lock held": o.lock != "HELD"}
    outcomes.append(o)

    o = killed("kill-figures (kill -9 while encoding the video)", base, work, ["figures"],
               video, signal.SIGKILL)
    time.sleep(2.0)
    o.checks = {"killed": o.status == -9, "unchanged": not o.changed,
                "no lock held": o.lock != "HELD", "ffmpeg gone after 2 s":
                ffmpeg_children(work / "kill-figures") == 0}
    outcomes.append(o)

    run_dir = work / "kill-figures"
    before = snapshot(run_dir)
    o = finish("rerun-figures (figures again after the kill -9)", start("figures", str(run_dir)),
               run_dir, before, [])
    o.checks = {"exit 0": o.status == 0, "temporary files swept": not o.temporary,
                "video as before": "video.mp4" not in o.changed, "lock gone": o.lock == "none"}
    outcomes.append(o)

    o = killed("sigint-figures (Ctrl-C to the group, video)", base, work, ["figures"], video,
               signal.SIGINT, group=True)
    o.checks = {**one_line(o, 130), "no temporary files": not o.temporary,
                "no ffmpeg": o.ffmpeg == 0}
    outcomes.append(o)

    o = killed("sigterm-figures (SIGTERM, video)", base, work, ["figures"], video,
               signal.SIGTERM)
    o.checks = {**one_line(o, 143), "no temporary files": not o.temporary,
                "no ffmpeg": o.ffmpeg == 0}
    outcomes.append(o)

    outcomes.append(commit_interrupted(base, work, ["learn", "--k-max", "5"], renames=5))

    run_dir = copy(base, work, "concurrent")
    before = snapshot(run_dir)
    first = start("figures", str(run_dir))
    seen = wait_for_line(first, "== figures")
    second = run("run", "--quick", "--seed", "2", "--out", str(run_dir))
    o = finish("concurrent (figures; run --seed 2 meanwhile)", first, run_dir, before, seen)
    o.errors = second.stderr.splitlines()
    o.checks = {"first exit 0": o.status == 0, "second exit 1": second.returncode == 1,
                "second: one line naming the holder": len(o.errors) == 1
                and f"pid {first.pid}" in o.errors[0],
                "only the report and its page changed": set(o.changed) <= {"report.json",
                                                                            "report.html"}}
    o.status = f"{o.status}/{second.returncode}"
    outcomes.append(o)

    run_dir = copy(base, work, "stale")
    run("observe", "--quick", "--seed", "3", str(run_dir))
    before = snapshot(run_dir)
    o = finish("stale (observe --seed 3, then figures)", start("figures", str(run_dir)),
               run_dir, before, [])
    o.checks = {**one_line(o, 1), "names model.npz": "model.npz" in "".join(o.errors)}
    outcomes.append(o)

    run_dir = copy(base, work, "failed-optimize")
    (run_dir / "model.npz").write_bytes(b"")
    before = snapshot(run_dir)
    o = finish("failed-optimize (empty model.npz, --collision-weight 30)",
               start("optimize", str(run_dir), "--collision-weight", "30"), run_dir, before, [])
    o.checks = one_line(o, 1)
    outcomes.append(o)

    before = snapshot(run_dir)
    o = finish("forced-optimize (the same with --force: the stage fails)",
               start("optimize", str(run_dir), "--collision-weight", "30", "--force"), run_dir,
               before, [])
    o.checks = one_line(o, 1)
    outcomes.append(o)

    folder = work / "foreign"
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir()
    (folder / "config.json").write_text('{"lr": 0.1}\n')
    before = snapshot(folder)
    o = finish("foreign (observe --quick into a folder holding another tool's config.json)",
               start("observe", "--quick", str(folder)), folder, before, [])
    o.checks = {**one_line(o, 1), "no lock written": o.lock == "none",
                "names the folder and --into-existing": f"{folder} holds config.json"
                in "".join(o.errors) and "--into-existing" in "".join(o.errors)}
    outcomes.append(o)

    run_dir = copy(base, work, "corrupt-report")
    (run_dir / "report.json").write_text("garbage{")
    before = snapshot(run_dir)
    o = finish("corrupt-report (replay --particles 10)",
               start("replay", str(run_dir), "--particles", "10"), run_dir, before, [])
    o.checks = one_line(o, 1)
    outcomes.append(o)
    return outcomes


def table(outcomes: list[Outcome]) -> str:
    rows = [("case", "exit", "changed", "temp files", "lock", "ffmpeg", "verdict")]
    for o in outcomes:
        rows.append((
            o.case, str(o.status), ", ".join(o.changed) or "nothing",
            str(len(o.temporary)), o.lock, str(o.ffmpeg), o.verdict,
        ))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = [" | ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)) for r in rows]
    lines.insert(1, "-+-".join("-" * w for w in widths))
    lines += ["", "stderr of each case (besides `== stage`):"]
    for o in outcomes:
        lines += [f"  {o.case.split()[0]}: {line}" for line in o.errors] or [
            f"  {o.case.split()[0]}: (nothing)"
        ]
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--base", type=Path, help="a finished quick run (made if not given)")
    parser.add_argument("--work", type=Path, help="where the copies go (default: a temp dir)")
    args = parser.parse_args()
    work = (args.work or Path(tempfile.mkdtemp(prefix="faults-"))).resolve()
    work.mkdir(parents=True, exist_ok=True)
    base = args.base
    if base is None:
        base = work / "base"
        made = run("run", "--quick", "--out", str(base))
        if made.returncode != 0:
            print(made.stderr, file=sys.stderr)
            return 1
    start_time = time.perf_counter()
    outcomes = cases(base.resolve(), work)
    print(table(outcomes))
    print(f"\n{len(outcomes)} cases in {time.perf_counter() - start_time:.0f} s, copies in {work}")
    return 0 if all(o.verdict == "OK" for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
