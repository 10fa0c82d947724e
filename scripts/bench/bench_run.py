"""Stage timings of a whole run, cold (empty numba cache) and warm, and where the time goes.

    python scripts/bench/bench_run.py [--quick] [--keep DIR]

Runs ``imitate run`` twice, each in a child process under a pseudo-terminal (so the progress bars
show as they do on a terminal): first with ``NUMBA_CACHE_DIR`` pointing at a new, empty
directory (cold: numba compiles every kernel the run calls), then with the same directory
(warm: numba loads them). The child wraps a few functions in timers:

- every numba dispatcher's ``compile`` (a compile, or a load from the cache), in processor time
  (robust to a shared machine), exclusive of the kernels it compiles in turn, and attributed to
  the kernel's module;
- the observation stage's own ``timing`` (rendering, tracking, ...);
- the planner (``plan_from_model``), the physics replays (in threads: their times summed), the
  video (``write_video``, which renders its frames as it encodes them) and the figures'
  snapshot rendering.

It prints per stage the wall time, its processor time (the child's threads and the processes
it waited for, as the video encoder: less sensitive than the wall time to a shared machine),
these parts, the longest silence on the terminal (the longest time between two writes of the
child, progress bars included) and the load average, then the compile or load time per module.
``PYTHONPATH=DIR`` runs another tree's ``imitate`` (its path is printed).
"""

from __future__ import annotations

import argparse
import fcntl
import functools
import json
import os
import pty
import resource
import select
import struct
import subprocess
import sys
import tempfile
import termios
import time
from collections import defaultdict
from pathlib import Path

STAGES = ("observe", "learn", "optimize", "replay", "figures")


# --- The child: one `imitate run` with timers -----------------------------------------------------


class _Timers:
    """Inclusive timers per (stage, part) and numba compile times per (stage, module)."""

    def __init__(self):
        self.stage = "startup"
        self.parts: dict[str, dict[str, float]] = defaultdict(lambda: defaultdict(float))
        self.numba: dict[str, dict[str, float]] = defaultdict(lambda: defaultdict(float))
        self.stage_wall: dict[str, float] = {}
        self.stage_cpu: dict[str, float] = {}
        self._numba_stack: list[float] = []  # children's time of each open compile

    def wrap(self, owner, name: str, part: str) -> None:
        """Time calls of ``owner.name`` (skipped if it has no such attribute)."""
        original = getattr(owner, name, None)
        if original is None:
            return

        @functools.wraps(original)
        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                self.parts[self.stage][part] += time.perf_counter() - start

        setattr(owner, name, timed)

    def wrap_numba(self) -> None:
        """Time every numba ``Dispatcher.compile`` (compile or cache load), exclusive of nested
        compiles of the kernels it calls."""
        from numba.core import dispatcher

        original = dispatcher.Dispatcher.compile
        timers = self

        def compile(disp, sig):
            timers._numba_stack.append(0.0)
            start = time.thread_time()  # processor time: numba compiles in this thread
            try:
                return original(disp, sig)
            finally:
                elapsed = time.thread_time() - start
                nested = timers._numba_stack.pop()
                if timers._numba_stack:
                    timers._numba_stack[-1] += elapsed
                module = getattr(disp.py_func, "__module__", "?")
                timers.numba[timers.stage][module] += elapsed - nested

        dispatcher.Dispatcher.compile = compile


def cpu_seconds() -> float:
    """User and system time of this process (all threads) and its waited-for children [s]."""
    return sum(
        usage.ru_utime + usage.ru_stime
        for usage in map(resource.getrusage, (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    )


def child(out: Path, argv: list[str], result: Path) -> int:
    start = time.perf_counter()
    timers = _Timers()
    timers.wrap_numba()  # before imitate: kernels compiled at import count too
    from imitate import cli
    from imitate.envs import video
    from imitate.stages import figures, optimize, replay, runner
    from imitate.stages import observe as observe_stage

    def observed(original):
        @functools.wraps(original)
        def watch(*args, timing=None, **kwargs):
            timing = {} if timing is None else timing
            try:
                return original(*args, timing=timing, **kwargs)
            finally:
                for key, value in timing.items():
                    if key != "pairs":
                        timers.parts["observe"][f"observe timing: {key}"] += value

        return watch

    observe_stage.watch = observed(observe_stage.watch)
    timers.wrap(optimize, "plan_from_model", "planner (plan_from_model)")
    timers.wrap(replay, "measure", "physics replays (summed over their threads)")
    timers.wrap(figures, "write_video", "video (frames + encoding)")
    timers.wrap(figures, "_snapshots", "fig8 snapshot rendering")
    timers.wrap(video, "write_video", "video (frames + encoding)")

    original_run_stage = runner.run_stage

    def run_stage(stage, *args, **kwargs):
        timers.stage = stage
        t0, c0 = time.perf_counter(), cpu_seconds()
        try:
            return original_run_stage(stage, *args, **kwargs)
        finally:
            timers.stage_wall[stage] = time.perf_counter() - t0
            timers.stage_cpu[stage] = cpu_seconds() - c0
            timers.stage = "end"

    runner.run_stage = run_stage
    timers.parts["startup"]["imports"] = time.perf_counter() - start
    status = cli.main(["run", "--out", str(out), *argv])
    result.write_text(
        json.dumps(
            {
                "status": status,
                "process_s": time.perf_counter() - start,
                "stage_wall": timers.stage_wall,
                "stage_cpu": timers.stage_cpu,
                "imitate": str(Path(cli.__file__).parent),
                "parts": timers.parts,
                "numba": timers.numba,
            }
        )
    )
    return status


# --- The parent: run the children, print the tables --------------------------------------------


def load() -> str:
    return " ".join(f"{v:.2f}" for v in os.getloadavg())


def run_child(out: Path, argv: list[str], cache: Path, result: Path) -> dict:
    """One child under a pseudo-terminal; returns its timers, report and silences."""
    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    env.setdefault("MUJOCO_GL", "egl")
    command = [sys.executable, __file__, "--child", str(out), "--result", str(result), *argv]
    master, slave = pty.openpty()
    # A terminal of 100 columns: with none set, tqdm draws bars 0 wide, i.e. nothing.
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 40, 100, 0, 0))
    load_before = load()
    start = time.perf_counter()
    proc = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=slave, stderr=slave, env=env)
    os.close(slave)
    stage, last, text = "startup", start, b""
    silence: dict[str, float] = defaultdict(float)
    while True:
        ready, _, _ = select.select([master], [], [], 1.0)
        if not ready:
            if proc.poll() is not None:
                break
            continue
        try:
            chunk = os.read(master, 65536)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        now = time.perf_counter()
        silence[stage] = max(silence[stage], now - last)
        last = now
        text += chunk
        for line in chunk.decode(errors="replace").splitlines():
            if line.startswith("== ") and line[3:].strip() in STAGES:
                stage = line[3:].strip()
    proc.wait()
    os.close(master)
    wall = time.perf_counter() - start
    if proc.returncode != 0:
        sys.stdout.write(text.decode(errors="replace")[-4000:])
        raise SystemExit(f"imitate run failed with status {proc.returncode}")
    (out.parent / f"{out.name}.log").write_bytes(text)
    timers = json.loads(result.read_text())
    report = json.loads((out / "report.json").read_text())
    return {
        "timers": timers,
        "report": report,
        "silence": silence,
        "wall": wall,
        "load": (load_before, load()),
    }


def breakdown(run: dict, stage: str) -> dict[str, float]:
    """``{part: seconds}`` of ``stage``: numba's processor time, then the timed parts (wall)."""
    timers = run["timers"]
    numba = sum(timers["numba"].get(stage, {}).values())
    out = {"numba compile/load (processor time)": numba} if numba > 0.005 else {}
    out.update(timers["parts"].get(stage, {}))
    return out


def print_tables(runs: dict[str, dict]) -> None:
    names = list(runs)
    print(f"{'stage / part':<44}" + "".join(f"{name + ' [s]':>12}" for name in names))
    for name in names:
        print(f"  load average at start, end of {name}: {runs[name]['load'][0]} | "
              f"{runs[name]['load'][1]}")
    rows = [("startup (imports)", {n: runs[n]["timers"]["parts"]["startup"]["imports"]
                                   for n in names})]
    for stage in STAGES:
        rows.append((stage, {n: runs[n]["report"]["timings"][stage] for n in names}))
        rows.append(("  processor time (all threads, children)",
                     {n: runs[n]["timers"]["stage_cpu"].get(stage) for n in names}))
        parts = {n: breakdown(runs[n], stage) for n in names}
        keys = list(dict.fromkeys(k for n in names for k in parts[n]))
        rows += [(f"  {key}", {n: parts[n].get(key) for n in names}) for key in keys]
        rows.append((
            "  longest silence on the terminal",
            {n: runs[n]["silence"].get(stage, 0.0) for n in names},
        ))
    rows.append(("total of the stages", {
        n: sum(runs[n]["report"]["timings"][s] for s in STAGES) for n in names}))
    rows.append(("  processor time", {
        n: sum(runs[n]["timers"]["stage_cpu"].values()) for n in names}))
    rows.append(("process (imports and stages)", {n: runs[n]["timers"]["process_s"]
                                                  for n in names}))
    rows.append(("longest silence before the first stage",
                 {n: runs[n]["silence"].get("startup", 0.0) for n in names}))
    for label, values in rows:
        cells = "".join(
            f"{'':>12}" if values.get(n) is None else f"{values[n]:12.1f}" for n in names
        )
        print(f"{label:<44}{cells}")

    print(f"\n{'numba compile / load per module, CPU':<44}"
          + "".join(f"{name + ' [s]':>12}" for name in names))
    modules: dict[str, dict[str, float]] = defaultdict(dict)
    for n in names:
        for stage_modules in runs[n]["timers"]["numba"].values():
            for module, seconds in stage_modules.items():
                modules[module][n] = modules[module].get(n, 0.0) + seconds
    for module in sorted(modules, key=lambda m: -max(modules[m].values())):
        cells = "".join(f"{modules[module].get(n, 0.0):12.2f}" for n in names)
        print(f"  {module:<42}{cells}")
    totals = "".join(f"{sum(m.get(n, 0.0) for m in modules.values()):12.2f}" for n in names)
    print(f"  {'all':<42}{totals}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="imitate run --quick")
    parser.add_argument("--keep", type=Path, help="keep the run directories here")
    parser.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    parser.add_argument("--result", type=Path, help=argparse.SUPPRESS)
    args, rest = parser.parse_known_args()
    if args.child:
        sys.exit(child(args.child, rest, args.result))
    argv = (["--quick"] if args.quick else []) + rest
    with tempfile.TemporaryDirectory(prefix="bench_run-") as tmp:
        base = args.keep or Path(tmp)
        base.mkdir(parents=True, exist_ok=True)
        cache = Path(tmp) / "numba-cache"
        cache.mkdir()
        runs = {}
        for name in ("cold", "warm"):
            print(f"{name} run ... (load average {load()})", file=sys.stderr, flush=True)
            runs[name] = run_child(base / name, argv, cache, Path(tmp) / f"{name}.json")
        where = runs["cold"]["timers"]["imitate"]
        print(f"imitate run {' '.join(argv)}".rstrip() + f" ({where}); {os.cpu_count()} cores")
        print_tables(runs)


if __name__ == "__main__":
    main()
