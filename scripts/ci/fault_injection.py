"""Kill, interrupt and race ``imitate`` on copies of one quick run; print what each leaves behind.

    MUJOCO_GL=egl python scripts/ci/fault_injection.py [--base runs/quick] [--work /tmp/faults]
        [--only NAME,NAME | --fast]

Without ``--base`` it first makes one (``imitate run --quick``). Every case (:data:`CASES`, in
order; ``--only`` picks some by name, ``--fast`` those of :data:`FAST`, a few seconds each, which
``tests/test_fault_injection.py`` runs) works on a fresh copy of it and prints one row: the exit
status, what changed in the directory (against the copy as it was just before the command), the
temporary files and the lock left in it, the ffmpeg children still running when the command had
exited, and a verdict against what the README promises (a stage that does not finish changes
nothing; one line on stderr; nothing outside the run directory is written or deleted; one command
at a time in a run directory, ``eval`` included). A kill checks that it landed mid-stage: the
command had printed its ``== stage`` line (or begun its video) and was still running. Two cases
are instrumented: a wrapper around ``imitate.cli.main`` sends SIGTERM just before each rename of a
stage's commit in turn, which must wait for the whole commit, and SIGKILL before one rename of
figures' commit, which the next command must report. The error lines follow the table.
Takes about ten minutes on two cores (``--fast``: about a minute).
"""

from __future__ import annotations

import argparse
import fcntl
import hashlib
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

IMITATE = (sys.executable, "-m", "imitate")
TEMPORARY = ".*.partial*"
VIDEO = ".video.mp4.*.partial.mp4"  # the video while ffmpeg encodes it
# the eval suite of the eval cases: one variation of a 3-iteration plan, one replay, few particles
TINY_SUITE = "variations = 1\nmax_iter = 3\nreplays = 1\nparticles = [4, 6]\n"
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
# the same, sending SIGKILL instead: the commit is cut between two renames
KILL_AT_RENAME = SIGTERM_AT_RENAME.replace("signal.SIGTERM", "signal.SIGKILL")


@dataclass
class Outcome:
    """What one case did: the command's exit status and stderr, and its directory afterwards."""

    case: str
    status: int | str | None
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


Case = Callable[[Path, Path], list[Outcome]]
CASES: dict[str, Case] = {}  # by name, in the order they run
FAST: set[str] = set()  # the names of those that take a few seconds each


def case(name: str, fast: bool = False) -> Callable[[Case], Case]:
    """Registers a case ``f(base, work) -> [Outcome, ...]`` in :data:`CASES` (and :data:`FAST`)."""

    def register(function: Case) -> Case:
        CASES[name] = function
        if fast:
            FAST.add(name)
        return function

    return register


# ---------------------------------------------------------------------------------------------
# What a directory holds, and the commands


def snapshot(run_dir: Path) -> dict[str, str]:
    """sha256 of every file under ``run_dir`` by relative path (temporary files and the lock
    aside; symbolic links to folders are not followed)."""
    return {
        p.relative_to(run_dir).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(run_dir.rglob("*"))
        if p.is_file() and not p.match(TEMPORARY) and p.name != ".lock"
    }


def listing(folder: Path) -> dict[str, str]:
    """sha256 of every file under ``folder``, temporary and hidden ones included (a folder
    outside the run directory, which no command may touch)."""
    if not folder.exists():
        return {}
    return {
        p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*")) if p.is_file()
    }


def changes(before: dict[str, str], after: dict[str, str]) -> list[str]:
    """``["report.json", "+new", "-gone"]``: files changed, added, removed."""
    changed = [f for f in before if f in after and before[f] != after[f]]
    return changed + [f"+{f}" for f in after if f not in before] + [
        f"-{f}" for f in before if f not in after
    ]


def lock_state(run_dir: Path) -> str:
    """``"none"``, ``"stale"`` (a file nobody holds) or ``"HELD"``. Takes the lock for a moment:
    only for a directory where no command is starting."""
    path = run_dir / ".lock"
    if not path.exists():
        return "none"
    with open(path, "rb") as file:
        try:
            fcntl.flock(file, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            return "HELD"
    return "stale"


def holds_lock(run_dir: Path, process: subprocess.Popen) -> bool:
    """Whether ``process`` holds the lock of ``run_dir`` (its pid in the lock's record). Reads
    the record without taking the lock, which would make ``process`` fail to take it."""
    try:
        holder = json.loads((run_dir / ".lock").read_text())
    except (OSError, ValueError):
        return False
    return isinstance(holder, dict) and holder.get("pid") == process.pid


def wait_for_eval(run_dir: Path, process: subprocess.Popen, timeout: float = 120.0) -> bool:
    """Wait until the ``imitate eval`` ``process`` holds the lock of ``run_dir``, or has made
    ``run_dir/eval`` (an eval that takes no lock), for at most ``timeout`` [s] and while it
    runs; whether it holds the lock then."""
    end = time.monotonic() + timeout
    while time.monotonic() < end and process.poll() is None:
        if holds_lock(run_dir, process) or (run_dir / "eval").exists():
            break
        time.sleep(0.02)
    return holds_lock(run_dir, process)


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
    """``imitate ARGS`` in its own process group (a terminal's Ctrl-C goes to the group), acting
    on SIGINT as in a terminal even where this script runs with it ignored (a non-interactive
    shell ignores it in what it starts in the background, and an ignored signal stays ignored
    across exec; a caught one does not)."""
    main = threading.current_thread() is threading.main_thread()  # (only it sets handlers)
    previous = signal.signal(signal.SIGINT, signal.default_int_handler) if main else None
    try:
        return subprocess.Popen(
            [*IMITATE, *args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
            start_new_session=True,
        )
    finally:
        if main:
            signal.signal(signal.SIGINT, previous)


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([*IMITATE, *args], check=False, capture_output=True, text=True)


def wait_for_line(process: subprocess.Popen, text: str) -> list[str]:
    """Stderr lines read until one contains ``text`` (all of them if the process ends)."""
    lines = []
    for line in process.stderr:
        lines.append(line.rstrip("\n"))
        if text in line:
            break
    return lines


def wait_for_file(run_dir: Path, pattern: str, process: subprocess.Popen,
                  timeout: float = 120.0) -> bool:
    """Whether a file matching ``pattern`` appeared in ``run_dir`` within ``timeout`` [s],
    before ``process`` ended."""
    end = time.monotonic() + timeout
    while time.monotonic() < end and process.poll() is None:
        if any(run_dir.glob(pattern)):
            return True
        time.sleep(0.02)
    return False


def finish(case: str, process: subprocess.Popen, run_dir: Path, before: dict[str, str],
           seen: list[str]) -> Outcome:
    """Wait for ``process``, then describe ``run_dir``."""
    rest = process.stderr.read().splitlines()
    status = process.wait()
    return describe(case, status, [*seen, *rest], run_dir, before)


def describe(case: str, status: int | str | None, lines: list[str], run_dir: Path,
             before: dict[str, str]) -> Outcome:
    """A row: ``run_dir`` now against ``before``, after a command that exited with ``status``
    and printed ``lines`` on stderr."""
    lines = [line for line in lines if line.strip() and not line.startswith("== ")]
    folders = [run_dir, *(p for p in run_dir.iterdir() if p.is_dir() and not p.is_symlink())]
    return Outcome(
        case, status, lines, changes(before, snapshot(run_dir)),
        [p.name for folder in folders for p in folder.glob(TEMPORARY)],
        lock_state(run_dir), ffmpeg_children(run_dir),
    )


def errors_of(outcome: Outcome) -> list[str]:
    """The error lines of ``outcome``, its warnings aside."""
    return [line for line in outcome.errors if not line.startswith("warning: ")]


def one_line(outcome: Outcome, status: int) -> dict[str, bool]:
    """The checks of a command that must fail with ``status`` and one line (warnings aside),
    changing nothing."""
    errors = errors_of(outcome)
    return {
        f"exit {status}": outcome.status == status,
        "one line": len(errors) == 1 and errors[0].startswith("imitate "),
        "unchanged": not outcome.changed,
        "no lock held": outcome.lock != "HELD",
    }


def refused_by(lines: list[str], holder: subprocess.Popen, command: str) -> bool:
    """Whether ``lines`` (warnings aside) are one error line naming ``holder`` (its pid and
    ``imitate COMMAND``) as the lock's holder."""
    errors = [line for line in lines if line.strip() and not line.startswith("warning: ")]
    return (
        len(errors) == 1 and errors[0].startswith("imitate ") and f"pid {holder.pid}" in errors[0]
        and f"imitate {command}" in errors[0]
    )


def killed(case: str, base: Path, work: Path, args: list[str], wait: str, sig: int,
           group: bool = False) -> Outcome:
    """Start ``imitate ARGS`` on a copy, wait for stderr ``== stage`` (``wait``) or a file
    (``wait`` a glob), then send ``sig`` (to the process group if ``group``). Its first check:
    the signal was sent mid-stage (``wait`` seen, the command still running)."""
    run_dir = copy(base, work, case)
    before = snapshot(run_dir)
    process = start(*args, str(run_dir))
    if wait.startswith("=="):
        seen = wait_for_line(process, wait)
        saw = any(wait in line for line in seen)
    else:
        saw = wait_for_file(run_dir, wait, process)
        seen = [] if saw else ["(never saw " + wait + ")"]
    running = process.poll() is None
    if running:  # (once reaped, its pid may be another process's)
        (os.killpg if group else os.kill)(process.pid, sig)
    o = finish(case, process, run_dir, before, seen)
    o.checks = {"sent mid-stage": saw and running}
    return o


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
    statuses, equal, saved = [], True, True
    last: Outcome | None = None
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
    assert last is not None
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
    shutil.copytree(base, run_dir, symlinks=True)
    return run_dir


def fresh(folder: Path) -> Path:
    """``folder``, empty."""
    shutil.rmtree(folder, ignore_errors=True)
    folder.mkdir(parents=True)
    return folder


def tiny_suite(work: Path) -> Path:
    """The suite file of the eval cases (:data:`TINY_SUITE`): ``work/tiny.toml``."""
    path = work / "tiny.toml"
    path.write_text(TINY_SUITE)
    return path


def eval_args(run_dir: Path, work: Path, n: int, videos: int) -> list[str]:
    return ["eval", str(run_dir), "--suite", str(tiny_suite(work)), "--n", str(n),
            "--videos", str(videos), "--workers", "1"]


def compare_args(run_dir: Path, work: Path) -> list[str]:
    return ["compare", str(run_dir), "--suite", str(tiny_suite(work)), "--n", "1",
            "--similarity", "variance,uniform", "--workers", "1"]


def only_under(changed: list[str], folder: str) -> bool:
    """Whether every change of ``changed`` (:func:`changes`) is under ``folder/``."""
    return all(c.lstrip("+-").startswith(folder + "/") for c in changed)


# ---------------------------------------------------------------------------------------------
# The cases, in the order they run


@case("kill-observe", fast=True)
def kill_observe(base: Path, work: Path) -> list[Outcome]:
    """kill -9 once `== observe` is printed: killed mid-stage, nothing changed, no lock held."""
    o = killed("kill-observe (kill -9 in observe)", base, work, ["observe", "--quick"],
               "== observe", signal.SIGKILL)
    o.checks.update({"killed": o.status == -9, "unchanged": not o.changed,
                     "no lock held": o.lock != "HELD"})
    return [o]


@case("kill-learn", fast=True)
def kill_learn(base: Path, work: Path) -> list[Outcome]:
    """kill -9 once `== learn` (--k-max 30) is printed: killed mid-stage, nothing changed."""
    o = killed("kill-learn (kill -9 in learn, --k-max 30)", base, work,
               ["learn", "--k-max", "30"], "== learn", signal.SIGKILL)
    o.checks.update({"killed": o.status == -9, "unchanged": not o.changed,
                     "no lock held": o.lock != "HELD"})
    return [o]


@case("kill-figures")
def kill_figures(base: Path, work: Path) -> list[Outcome]:
    """kill -9 while ffmpeg encodes the video: nothing changed, ffmpeg gone within 2 s; then
    `figures` again (row rerun-figures): exit 0, the temporary files swept, the same video."""
    o = killed("kill-figures (kill -9 while encoding the video)", base, work, ["figures"],
               VIDEO, signal.SIGKILL)
    time.sleep(2.0)
    o.checks.update({"killed": o.status == -9, "unchanged": not o.changed,
                     "no lock held": o.lock != "HELD", "ffmpeg gone after 2 s":
                     ffmpeg_children(work / "kill-figures") == 0})
    run_dir = work / "kill-figures"
    before = snapshot(run_dir)
    again = finish("rerun-figures (figures again after the kill -9)",
                   start("figures", str(run_dir)), run_dir, before, [])
    again.checks = {"exit 0": again.status == 0, "temporary files swept": not again.temporary,
                    "video as before": "video.mp4" not in again.changed,
                    "lock gone": again.lock == "none"}
    return [o, again]


@case("sigint-figures")
def sigint_figures(base: Path, work: Path) -> list[Outcome]:
    """Ctrl-C (SIGINT to the process group) during the video: exit 130, one line, nothing
    changed, no temporary file, no ffmpeg left."""
    o = killed("sigint-figures (Ctrl-C to the group, video)", base, work, ["figures"], VIDEO,
               signal.SIGINT, group=True)
    o.checks.update({**one_line(o, 130), "no temporary files": not o.temporary,
                     "no ffmpeg": o.ffmpeg == 0})
    return [o]


@case("sigterm-figures")
def sigterm_figures(base: Path, work: Path) -> list[Outcome]:
    """SIGTERM during the video: exit 143, one line, nothing changed, no temporary file."""
    o = killed("sigterm-figures (SIGTERM, video)", base, work, ["figures"], VIDEO,
               signal.SIGTERM)
    o.checks.update({**one_line(o, 143), "no temporary files": not o.temporary,
                     "no ffmpeg": o.ffmpeg == 0})
    return [o]


@case("commit-sigterm")
def commit_sigterm(base: Path, work: Path) -> list[Outcome]:
    """SIGTERM just before each of the 5 renames of `learn --k-max 5`'s commit (instrumented):
    exit 143 and one line saying the stage was saved, the files those of an untouched learn."""
    return [commit_interrupted(base, work, ["learn", "--k-max", "5"], renames=5)]


@case("concurrent")
def concurrent(base: Path, work: Path) -> list[Outcome]:
    """`run --quick --seed 2` while `figures` runs: refused (exit 1, one line naming the
    holder); figures finishes, changing only the report and its page."""
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
    return [o]


@case("stale")
def stale(base: Path, work: Path) -> list[Outcome]:
    """`observe --seed 3`, then `figures`: refused (exit 1, one line naming model.npz)."""
    run_dir = copy(base, work, "stale")
    run("observe", "--quick", "--seed", "3", str(run_dir))
    before = snapshot(run_dir)
    o = finish("stale (observe --seed 3, then figures)", start("figures", str(run_dir)),
               run_dir, before, [])
    o.checks = {**one_line(o, 1), "names model.npz": "model.npz" in "".join(o.errors)}
    return [o]


@case("failed-optimize", fast=True)
def failed_optimize(base: Path, work: Path) -> list[Outcome]:
    """`optimize --collision-weight 30` on an empty model.npz: exit 1, one line, unchanged
    (config.json too)."""
    run_dir = copy(base, work, "failed-optimize")
    (run_dir / "model.npz").write_bytes(b"")
    before = snapshot(run_dir)
    o = finish("failed-optimize (empty model.npz, --collision-weight 30)",
               start("optimize", str(run_dir), "--collision-weight", "30"), run_dir, before, [])
    o.checks = one_line(o, 1)
    return [o]


@case("forced-optimize", fast=True)
def forced_optimize(base: Path, work: Path) -> list[Outcome]:
    """The same with --force (the stage itself fails on the empty file): exit 1, one line,
    unchanged."""
    run_dir = copy(base, work, "forced-optimize")
    (run_dir / "model.npz").write_bytes(b"")
    before = snapshot(run_dir)
    o = finish("forced-optimize (the same with --force: the stage fails)",
               start("optimize", str(run_dir), "--collision-weight", "30", "--force"), run_dir,
               before, [])
    o.checks = one_line(o, 1)
    return [o]


@case("foreign", fast=True)
def foreign(base: Path, work: Path) -> list[Outcome]:
    """`observe --quick` into a folder holding another tool's config.json: exit 1, one line
    naming the folder and --into-existing, the file kept, no lock written."""
    folder = fresh(work / "foreign")
    (folder / "config.json").write_text('{"lr": 0.1}\n')
    before = snapshot(folder)
    o = finish("foreign (observe --quick into a folder holding another tool's config.json)",
               start("observe", "--quick", str(folder)), folder, before, [])
    o.checks = {**one_line(o, 1), "no lock written": o.lock == "none",
                "names the folder and --into-existing": f"{folder} holds config.json"
                in "".join(o.errors) and "--into-existing" in "".join(o.errors)}
    return [o]


@case("corrupt-report", fast=True)
def corrupt_report(base: Path, work: Path) -> list[Outcome]:
    """`replay --particles 10` with report.json garbage: exit 1, one line, unchanged."""
    run_dir = copy(base, work, "corrupt-report")
    (run_dir / "report.json").write_text("garbage{")
    before = snapshot(run_dir)
    o = finish("corrupt-report (replay --particles 10)",
               start("replay", str(run_dir), "--particles", "10"), run_dir, before, [])
    o.checks = one_line(o, 1)
    return [o]


@case("symlink-figures", fast=True)
def symlink_figures(base: Path, work: Path) -> list[Outcome]:
    """`figures` with R/figures a symbolic link to an outside folder holding a user's
    `.notes.partial.txt` (review S2): exit 1, one line, the run unchanged, nothing written into
    the outside folder and the user's file still there."""
    run_dir = copy(base, work, "symlink-figures")
    outside = fresh(work / "symlink-figures-outside")
    notes = outside / ".notes.partial.txt"
    notes.write_text("a user's notes, named like a temporary file\n")
    shutil.rmtree(run_dir / "figures")
    (run_dir / "figures").symlink_to(outside, target_is_directory=True)
    before, outside_before = snapshot(run_dir), listing(outside)
    o = finish("symlink-figures (R/figures a link to an outside folder)",
               start("figures", str(run_dir)), run_dir, before, [])
    o.checks = {**one_line(o, 1), "nothing written outside": listing(outside) == outside_before,
                "the user's .notes.partial.txt kept": notes.is_file()}
    return [o]


@case("symlink-lock", fast=True)
def symlink_lock(base: Path, work: Path) -> list[Outcome]:
    """`learn` with R/.lock a symbolic link to an outside file (review C5): exit 1, one line,
    the run unchanged, the outside file's content as it was."""
    run_dir = copy(base, work, "symlink-lock")
    victim = work / "symlink-lock-victim.txt"
    victim.write_text("do not truncate me\n")
    (run_dir / ".lock").symlink_to(victim)
    before = snapshot(run_dir)
    o = finish("symlink-lock (R/.lock a link to an outside file; learn)",
               start("learn", str(run_dir)), run_dir, before, [])
    o.checks = {**one_line(o, 1),
                "outside file as it was": victim.read_text() == "do not truncate me\n"}
    return [o]


@case("traversal")
def traversal(base: Path, work: Path) -> list[Outcome]:
    """A results.jsonl record under the evaluation's own digest whose outcome is a `../` path
    to a file outside the run (review S5): `eval --videos 1` exits 0, writes nothing outside
    (the target's folder is not even made), skips the record (runs the variation again) and
    names its failure videos by known outcomes only. The record comes from a first `eval`."""
    run_dir = copy(base, work, "traversal")
    outside = work / "traversal-outside"
    shutil.rmtree(outside, ignore_errors=True)
    first = run(*eval_args(run_dir, work, n=1, videos=0))
    results = sorted(run_dir.glob("eval/**/results.jsonl"))
    if first.returncode != 0 or len(results) != 1:
        o = Outcome("traversal (the first eval failed)", first.returncode,
                    first.stderr.splitlines(), [], [], lock_state(run_dir), 0)
        o.checks = {"first eval exit 0": first.returncode == 0,
                    "one results.jsonl": len(results) == 1}
        return [o]
    record = json.loads(results[0].read_text().splitlines()[0])
    climb = len((results[0].parent / "failures" / record["digest"] / "0000-x").parts) + 2
    record["outcome"] = "x/" + "../" * climb + str(outside / "ESCAPED").lstrip("/")
    record["settings"]["obstacle"] = None
    crafted = json.dumps(record)
    results[0].write_text(crafted + "\n")
    before = snapshot(run_dir)
    o = finish("traversal (a results.jsonl record's outcome a ../ path; eval --videos 1)",
               start(*eval_args(run_dir, work, n=1, videos=1)), run_dir, before, [])
    lines = results[0].read_text().splitlines()
    later = [json.loads(line) for line in lines[1:] if line.strip()]
    videos = [p.name for p in run_dir.glob("eval/**/failures/*/*")]
    o.checks = {
        "exit 0": o.status == 0, "no error": not errors_of(o),
        "nothing outside": not outside.exists()
        and not any(work.glob("**/ESCAPED*")),
        "record skipped: the variation ran again": lines[0] == crafted and [
            (r.get("digest"), r.get("id")) for r in later] == [(record["digest"], 0)]
        and "/" not in str(later[0].get("outcome")),
        "failure videos named ID-OUTCOME.mp4": all(
            re.fullmatch(r"\d{4}-[a-z_]+\.mp4", name) for name in videos
        ),
        "only eval/ changed": only_under(o.changed, "eval"), "no lock held": o.lock != "HELD",
    }
    return [o]


@case("two-evals")
def two_evals(base: Path, work: Path) -> list[Outcome]:
    """Two `eval`s of one run (tiny suite, --n 6: the first still running when the second has
    started, on a loaded machine too), the second started once the first holds the lock (or has
    made eval/, where eval takes no lock; review E6): the second exits 1 with one line naming
    the first; the first exits 0 and its results hold each id once; only eval/ changed."""
    run_dir = copy(base, work, "two-evals")
    before = snapshot(run_dir)
    args = eval_args(run_dir, work, n=6, videos=0)
    first = start(*args)
    holds = wait_for_eval(run_dir, first)
    second = run(*args)
    first_running = first.poll() is None
    o = finish("two-evals (eval --n 6; the same eval meanwhile)", first, run_dir, before, [])
    errors = second.stderr.splitlines()
    o.errors = [f"first: {line}" for line in o.errors] + errors
    ids = [json.loads(line)["id"] for path in run_dir.glob("eval/**/results.jsonl")
           for line in path.read_text().splitlines() if line.strip()]
    o.checks = {
        "first held the lock": holds, "first exit 0": o.status == 0,
        "second exit 1": second.returncode == 1,
        "second: one line naming the holder": refused_by(errors, first, "eval"),
        "second ended while the first ran": first_running,
        "each id once": sorted(ids) == list(range(6)),
        "only eval/ changed": only_under(o.changed, "eval"),
        "no lock held": o.lock != "HELD",
    }
    o.status = f"{o.status}/{second.returncode}"
    return [o]


@case("eval-against-stage")
def eval_against_stage(base: Path, work: Path) -> list[Outcome]:
    """`learn` while an `eval` (tiny suite, --n 2) holds the run: learn exits 1 with one line
    naming the eval; the eval exits 0; only eval/ changed (model.npz as it was)."""
    run_dir = copy(base, work, "eval-against-stage")
    before = snapshot(run_dir)
    evaluation = start(*eval_args(run_dir, work, n=2, videos=0))
    holds = wait_for_eval(run_dir, evaluation)
    stage = run("learn", str(run_dir))
    eval_running = evaluation.poll() is None
    o = finish("eval-against-stage (eval --n 2; learn meanwhile)", evaluation, run_dir, before,
               [])
    errors = stage.stderr.splitlines()
    o.errors = [f"eval: {line}" for line in o.errors] + [line for line in errors
                                                          if not line.startswith("== ")]
    o.checks = {
        "eval held the lock": holds, "eval exit 0": o.status == 0,
        "learn exit 1": stage.returncode == 1,
        "learn: one line naming the holder": refused_by(
            [line for line in errors if not line.startswith("== ")], evaluation, "eval"),
        "learn ended while the eval ran": eval_running,
        "only eval/ changed": only_under(o.changed, "eval"), "no lock held": o.lock != "HELD",
    }
    o.status = f"{o.status}/{stage.returncode}"
    return [o]


@case("sweep-foreign", fast=True)
def sweep_foreign(base: Path, work: Path) -> list[Outcome]:
    """`learn` pointed at a user's folder holding `.thesis.partial.tex` and
    `notes/.todo.partial.md` (review N-x2): exit 1, one line, both files kept (the lock's sweep
    runs in run directories only, on imitate's own temporary names)."""
    folder = fresh(work / "sweep-foreign")
    (folder / "notes").mkdir()
    (folder / ".thesis.partial.tex").write_text("draft\n")
    (folder / "notes" / ".todo.partial.md").write_text("x\n")
    before, kept = snapshot(folder), listing(folder)
    o = finish("sweep-foreign (learn in a user's folder of .*.partial* files)",
               start("learn", str(folder)), folder, before, [])
    o.checks = {**one_line(o, 1), "the user's files kept": listing(folder) == kept}
    return [o]


@case("hardlink-lock", fast=True)
def hardlink_lock(base: Path, work: Path) -> list[Outcome]:
    """`learn` with R/.lock a hard link to a user's file (review N-x1): exit 1, one line, the
    run unchanged, the file's content as it was."""
    run_dir = copy(base, work, "hardlink-lock")
    victim = work / "hardlink-lock-notes.txt"
    victim.write_text("notes\n")
    os.link(victim, run_dir / ".lock")
    before = snapshot(run_dir)
    o = finish("hardlink-lock (R/.lock a hard link to a user's file; learn)",
               start("learn", str(run_dir)), run_dir, before, [])
    o.checks = {**one_line(o, 1), "the user's file as it was": victim.read_text() == "notes\n"}
    return [o]


@case("symlink-eval", fast=True)
def symlink_eval(base: Path, work: Path) -> list[Outcome]:
    """`eval` with R/eval a symbolic link to an outside folder (review S4)."""
    return _linked_folder(base, work, "eval", lambda run_dir: eval_args(run_dir, work, n=1,
                                                                        videos=0))


@case("symlink-export", fast=True)
def symlink_export(base: Path, work: Path) -> list[Outcome]:
    """`export --format hdf5` with R/export a symbolic link to an outside folder (review S10)."""
    return _linked_folder(base, work, "export",
                          lambda run_dir: ("export", str(run_dir), "--format", "hdf5"))


def _linked_folder(
    base: Path, work: Path, folder: str, args: Callable[[Path], Sequence[str]]
) -> list[Outcome]:
    """``imitate ARGS`` with ``R/folder`` a symbolic link to an outside folder: exit 1, one
    line, nothing written outside."""
    run_dir = copy(base, work, f"symlink-{folder}")
    outside = fresh(work / f"symlink-{folder}-outside")
    (run_dir / folder).symlink_to(outside, target_is_directory=True)
    before = snapshot(run_dir)
    o = finish(f"symlink-{folder} (R/{folder} a link to an outside folder)",
               start(*args(run_dir)), run_dir, before, [])
    o.checks = {**one_line(o, 1), "nothing written outside": listing(outside) == {}}
    return [o]


@case("symlink-compare", fast=True)
def symlink_compare(base: Path, work: Path) -> list[Outcome]:
    """`compare` with R/compare a symbolic link to an outside folder."""
    return _linked_folder(base, work, "compare", lambda run_dir: compare_args(run_dir, work))


@case("hardlink-compare-results", fast=True)
def hardlink_compare_results(base: Path, work: Path) -> list[Outcome]:
    """`compare` whose results.jsonl is a hard link to a user's file (review F): exit 1, one
    line, the user's file as it was."""
    run_dir = copy(base, work, "hardlink-compare-results")
    victim = work / "hardlink-compare-notes.txt"
    victim.write_text("notes\n")
    folder = run_dir / "compare" / "tiny"
    folder.mkdir(parents=True)
    os.link(victim, folder / "results.jsonl")
    before = snapshot(run_dir)
    o = finish("hardlink-compare-results (R/compare/tiny/results.jsonl a hard link to a user's "
               "file)", start(*compare_args(run_dir, work)), run_dir, before, [])
    o.checks = {**one_line(o, 1), "the user's file as it was": victim.read_text() == "notes\n"}
    return [o]


@case("eval-other-task")
def eval_other_task(base: Path, work: Path) -> list[Outcome]:
    """`eval` after `observe --quick --task insert` into a pour run (review A: the pour model was
    evaluated in the insert scene): exit 1, one line naming the model, nothing changed."""
    run_dir = copy(base, work, "eval-other-task")
    observed = subprocess.run([sys.executable, "-m", "imitate", "observe", "--quick", "--task",
                               "insert", str(run_dir)], capture_output=True, text=True, check=False)
    before = snapshot(run_dir)
    o = finish("eval-other-task (eval of a pour model after observe --task insert)",
               start("eval", str(run_dir), "--n", "1", "--videos", "0", "--workers", "1"),
               run_dir, before, [])
    o.checks = {"observe exit 0": observed.returncode == 0, **one_line(o, 1),
                "names model.npz": "model.npz" in "".join(o.errors)}
    return [o]


@case("eval-out-foreign", fast=True)
def eval_out_foreign(base: Path, work: Path) -> list[Outcome]:
    """`eval --out F`, F a user's folder holding report.html and summary.json (review N-x3), or
    report.html and a results.jsonl of their notes (the review's follow-up of B): exit 1, one
    line, the files kept."""
    run_dir = copy(base, work, "eval-out-foreign")
    outcomes = []
    for label, second, text in (("a user's folder", "summary.json", '{"mine": 1}\n'),
                                ("a folder of notes named results.jsonl", "results.jsonl",
                                 "my lab notes\nday 2\n")):
        folder = fresh(work / "eval-out-foreign-F")
        (folder / "report.html").write_text("<h1>my page</h1>\n")
        (folder / second).write_text(text)
        before, kept = snapshot(run_dir), listing(folder)
        o = finish(f"eval-out-foreign (eval --out {label})",
                   start(*eval_args(run_dir, work, n=1, videos=0), "--out", str(folder)),
                   run_dir, before, [])
        o.checks = {**one_line(o, 1), "the user's files kept": listing(folder) == kept}
        outcomes.append(o)
    return outcomes


@case("stale-eval")
def stale_eval(base: Path, work: Path) -> list[Outcome]:
    """`observe --seed 3`, then `eval`, then `compare` (review A: eval labelled seed 0's model
    teacher 3): each exit 1, one line naming model.npz, nothing changed."""
    run_dir = copy(base, work, "stale-eval")
    run("observe", "--quick", "--seed", "3", str(run_dir))
    outcomes = []
    for command, args in (("eval", eval_args(run_dir, work, n=1, videos=0)),
                          ("compare", compare_args(run_dir, work))):
        before = snapshot(run_dir)
        o = finish(f"stale-eval (observe --seed 3, then {command})", start(*args), run_dir,
                   before, [])
        o.checks = {**one_line(o, 1), "names model.npz": "model.npz" in "".join(o.errors)}
        outcomes.append(o)
    return outcomes


@case("eval-torn-first-record")
def eval_torn_first_record(base: Path, work: Path) -> list[Outcome]:
    """`eval` into its folder whose results.jsonl holds half a first record (review B: refused,
    the resume lost): exit 0, each variation once."""
    run_dir = copy(base, work, "eval-torn-first-record")
    folder = run_dir / "eval" / "tiny-w10000-variance"
    folder.mkdir(parents=True)
    (folder / "results.jsonl").write_text('{"digest": "92')
    before = snapshot(run_dir)
    o = finish("eval-torn-first-record (eval after half a first record)",
               start(*eval_args(run_dir, work, n=2, videos=0)), run_dir, before, [])
    ids = sorted(record["id"] for record in _whole_lines(folder / "results.jsonl"))
    o.checks = {"exit 0": o.status == 0, "no error": not errors_of(o),
                "each id once": ids == [0, 1]}
    return [o]


def _whole_lines(path: Path) -> list[dict]:
    """The lines of ``path`` that are JSON objects."""
    found = []
    for line in path.read_text(errors="replace").splitlines():
        try:
            value = json.loads(line)
        except ValueError:
            continue
        if isinstance(value, dict):
            found.append(value)
    return found


@case("null-report-value", fast=True)
def null_report_value(base: Path, work: Path) -> list[Outcome]:
    """`learn` with a null `perception.pos_err_mm_median` in report.json (review C: the page
    crashed): exit 0, no traceback."""
    run_dir = copy(base, work, "null-report-value")
    report = json.loads((run_dir / "report.json").read_text())
    report["perception"]["pos_err_mm_median"] = None
    (run_dir / "report.json").write_text(json.dumps(report))
    before = snapshot(run_dir)
    o = finish("null-report-value (learn, perception.pos_err_mm_median null)",
               start("learn", str(run_dir)), run_dir, before, [])
    o.checks = {"exit 0": o.status == 0,
                "no traceback": not any("Traceback" in line for line in o.errors)}
    return [o]


@case("fifo", fast=True)
def fifo(base: Path, work: Path) -> list[Outcome]:
    """config.json a FIFO, then `replay`; an evaluation's summary.json a FIFO, then `eval` (review
    D: each waited for a writer, holding the lock): exit 1 within 60 s, one line."""
    outcomes = []
    for name, file, args in (
        ("replay", "config.json", lambda r: ["replay", str(r)]),
        ("eval", "eval/tiny-w10000-variance/summary.json",
         lambda r: eval_args(r, work, n=1, videos=0)),
    ):
        run_dir = copy(base, work, f"fifo-{name}")
        path = run_dir / file
        path.parent.mkdir(parents=True, exist_ok=True)
        path.unlink(missing_ok=True)
        os.mkfifo(path)
        before = snapshot(run_dir)
        process = start(*args(run_dir))
        try:
            process.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
        o = finish(f"fifo ({file} a FIFO, then {name})", process, run_dir, before, [])
        o.checks = {**one_line(o, 1), "not a regular file": "not a regular file"
                    in "".join(o.errors)}
        outcomes.append(o)
    return outcomes


@case("long-value", fast=True)
def long_value(base: Path, work: Path) -> list[Outcome]:
    """`replay` with a 1 MB task name in config.json (review T10i: echoed whole): exit 1, one
    line under 1000 characters."""
    run_dir = copy(base, work, "long-value")
    config = json.loads((run_dir / "config.json").read_text())
    config["task"] = "x" * 10**6
    (run_dir / "config.json").write_text(json.dumps(config))
    before = snapshot(run_dir)
    o = finish("long-value (a 1 MB task in config.json, then replay)",
               start("replay", str(run_dir)), run_dir, before, [])
    o.checks = {**one_line(o, 1), "under 1000 characters": all(len(e) < 1000 for e in o.errors)}
    return [o]


@case("compare-null-record")
def compare_null_record(base: Path, work: Path) -> list[Outcome]:
    """`compare` after its first record's `mahalanobis` was made null (review C): the record runs
    again; exit 0, no traceback."""
    run_dir = copy(base, work, "compare-null-record")
    first = run(*compare_args(run_dir, work))
    results = next(run_dir.glob("compare/*/results.jsonl"))
    lines = results.read_text().splitlines()
    record = json.loads(lines[0])
    record["mahalanobis"] = None
    results.write_text("\n".join([json.dumps(record), *lines[1:]]) + "\n")
    before = snapshot(run_dir)
    o = finish("compare-null-record (compare, a record's mahalanobis null)",
               start(*compare_args(run_dir, work)), run_dir, before, [])
    o.checks = {"first compare exit 0": first.returncode == 0, "exit 0": o.status == 0,
                "no traceback": not any("Traceback" in line for line in o.errors)}
    return [o]


@case("commit-kill-figures")
def commit_kill_figures(base: Path, work: Path) -> list[Outcome]:
    """kill -9 just before the second rename into R of `figures --video-width 160
    --video-height 120`'s commit (instrumented; review N-d1: the new video and figures in place,
    config.json and the manifest old), then `replay`: replay exits 0 with a warning naming the
    cut commit of stage figures and `imitate figures`, and its page marks them out of date."""
    run_dir = copy(base, work, "commit-kill-figures")
    before = snapshot(run_dir)
    process = subprocess.Popen(
        [sys.executable, "-c", KILL_AT_RENAME, "2", str(run_dir), "figures", "--video-width",
         "160", "--video-height", "120"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
        text=True,
    )
    killed = finish("commit-kill-figures", process, run_dir, before, [])
    nxt = run("replay", str(run_dir))
    o = describe("commit-kill-figures (kill -9 in figures' commit; replay)",
                 f"{killed.status}/{nxt.returncode}", nxt.stderr.splitlines(), run_dir, before)
    warned = [line for line in o.errors if "the commit of stage figures was cut short" in line]
    page = (run_dir / "report.html").read_text()
    o.checks = {
        "killed mid-commit": killed.status == -9 and "video.mp4" in killed.changed
        and not {"config.json", "manifest.json"} & set(killed.changed),
        "replay exit 0": nxt.returncode == 0,
        "warned of the cut commit": len(warned) == 1 and f"imitate figures {run_dir}" in warned[0],
        "page: figures out of date": "Out of date: video.mp4" in page,
        "temporary files swept": not o.temporary, "no lock held": o.lock != "HELD",
    }
    return [o]


@case("kill-eval-workers")
def kill_eval_workers(base: Path, work: Path) -> list[Outcome]:
    """kill -9 of `eval --n 3 --workers 1` once its first record is written (review E2): its
    worker exits within 3 s by itself, printing nothing (no BrokenPipeError traceback)."""
    run_dir = copy(base, work, "kill-eval-workers")
    before = snapshot(run_dir)
    process = start(*eval_args(run_dir, work, n=3, videos=0))
    saw = wait_for_file(run_dir, "eval/*/results.jsonl", process)
    end = time.monotonic() + 120
    while time.monotonic() < end and process.poll() is None and not any(
        path.stat().st_size for path in run_dir.glob("eval/*/results.jsonl")
    ):
        time.sleep(0.05)
    workers = children(process.pid)
    running = process.poll() is None
    if running:
        os.kill(process.pid, signal.SIGKILL)
    process.wait()
    time.sleep(3.0)
    left = [pid for pid in workers if Path(f"/proc/{pid}").exists()]
    o = finish("kill-eval-workers (kill -9 of eval after its first record)", process, run_dir,
               before, [])
    o.checks = {"sent mid-evaluation": saw and running and bool(workers),
                "workers gone within 3 s": not left,
                "no traceback": not any("Traceback" in line for line in o.errors)}
    return [o]


def children(pid: int) -> list[int]:
    """The pids of the running child processes of ``pid``."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


# ---------------------------------------------------------------------------------------------
# Running them


def run_cases(names: list[str], base: Path, work: Path) -> list[Outcome]:
    """The rows of the cases ``names`` (of :data:`CASES`) on copies of ``base`` under ``work``;
    a case that raises is a failed row naming the exception."""
    outcomes = []
    for name in names:
        try:
            outcomes += CASES[name](base, work)
        except Exception as err:  # a case's own failure (a file it expected missing): a row
            o = Outcome(f"{name} (raised)", None, [f"{type(err).__name__}: {err}"], [], [],
                        "?", 0)
            o.checks = {"ran to its end": False}
            outcomes.append(o)
    return outcomes


def select(only: str | None, fast: bool) -> list[str]:
    """The names of the cases to run, in :data:`CASES`' order.

    Raises:
        ValueError: a name of ``only`` (comma-separated) is not a case's; one line.
    """
    if only is None:
        return [name for name in CASES if name in FAST or not fast]
    names = [name.strip() for name in only.split(",") if name.strip()]
    unknown = [name for name in names if name not in CASES]
    if unknown or not names:
        raise ValueError(
            f"--only {only} not accepted: {', '.join(unknown) or 'no name'} is no case; one or "
            f"more (comma-separated) of {', '.join(CASES)}"
        )
    return [name for name in CASES if name in names]


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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="cases (* in --fast):\n" + "\n".join(
            f"  {name}{' *' if name in FAST else ''}: "
            + " ".join((CASES[name].__doc__ or "").split()) for name in CASES
        ),
    )
    parser.add_argument("--base", type=Path, help="a finished quick run (made if not given)")
    parser.add_argument("--work", type=Path, help="where the copies go (default: a temp dir)")
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--only", metavar="NAME,NAME", help="these cases only (names below)")
    which.add_argument("--fast", action="store_true",
                       help="the cases that take a few seconds each (* below)")
    args = parser.parse_args(argv)
    try:
        names = select(args.only, args.fast)
    except ValueError as err:
        print(f"{parser.prog}: error: {err}", file=sys.stderr)
        return 2
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
    outcomes = run_cases(names, base.resolve(), work)
    print(table(outcomes))
    seconds = time.perf_counter() - start_time
    print(f"\n{len(outcomes)} rows of {len(names)} cases in {seconds:.0f} s, copies in {work}")
    return 0 if all(o.verdict == "OK" for o in outcomes) else 1


if __name__ == "__main__":
    sys.exit(main())
