"""The default run's stage timings and the figures' share of them; or the parts of a run's stages
measured one at a time (``--parts``): what bounds each stage on a machine.

    python scripts/bench/bench_stages.py [--repeat N] [--quick]
    python scripts/bench/bench_stages.py --parts observe replay video [RUN_DIR] [--threads 1 2 4]

Without ``--parts``: ``imitate run`` (the default settings, ``--quick`` if given) ``--repeat``
times (default 1), each in a new temporary folder, in a child process whose progress goes to a
file (the stages as a redirected ``imitate run`` runs them), after ``python -m imitate.warmup``
(numba's kernels in its cache: no stage compiles). Prints each stage's seconds (the report's
``timings``; the median over the repeats), the total, the figures' share of it, the video's
frames and the load average before and after. ``PYTHONPATH=DIR`` runs another tree's ``imitate``
(its path is printed).

With ``--parts``, on the run ``RUN_DIR`` (default ``runs/latest``; its config, plan and replay):

- observe: the session's stereo pairs rendered in this thread (kept in memory: 1.7 GB for the
  default 905 pairs), tracked from memory with OpenCV's own threads and with one (as
  :func:`imitate.perception.track` does), then rendered ahead in a thread and tracked as the
  stage does. Every tracking must give the tracks of the first.
- replay: each of the stage's physics replays alone, then all of them in threads as the stage
  runs them (each one's wall time there too).
- video: the video's frames rendered in each of ``--threads`` threads (not encoded), as
  ``scripts/bench/bench_video.py --render`` does.

Prints the wall time and this process's processor time (all its threads) of each.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from imitate.envs.observation import ObservationConfig, frames, session
from imitate.envs.task import get_task
from imitate.perception import StereoTracker, perception_config, track
from imitate.perception import tracks as tracks_module
from imitate.perception.watch import cameras
from imitate.stages import figures
from imitate.stages import replay as replay_stage
from imitate.stages.config import load_config
from imitate.stages.files import ObservationsFile, PlanFile, ReplayFile


def timed(label: str, work):
    """``work()``, its wall and processor time printed after ``label``."""
    cpu, start = time.process_time(), time.perf_counter()
    result = work()
    print(f"{label:56s} {time.perf_counter() - start:8.2f} {time.process_time() - cpu:8.2f}",
          flush=True)
    return result


def observe(run_dir: Path, config, threads) -> None:
    watching = ObservationConfig(
        teacher=config.teacher(), fps=config.fps, width=config.width, height=config.height
    )
    sess = session(watching)

    def tracked(pairs):
        tracker = StereoTracker(*cameras(sess), perception_config(sess.motion.objects))
        return track(tracker, pairs, sess.times)

    pairs = timed(f"observe: render {len(sess.times)} pairs in this thread",
                  lambda: list(frames(sess, ahead=False)))
    one_thread = tracks_module._one_opencv_thread
    try:  # OpenCV's own threads, as the tracker used them before
        tracks_module._one_opencv_thread = contextlib.nullcontext
        first = timed("observe: track them, OpenCV's own threads", lambda: tracked(iter(pairs)))
    finally:
        tracks_module._one_opencv_thread = one_thread
    others = [timed("observe: track them, one OpenCV thread", lambda: tracked(iter(pairs)))]
    pairs.clear()  # 1.7 GB for the default session
    others.append(timed("observe: render ahead in a thread and track (the stage)",
                        lambda: tracked(frames(sess))))
    same = all(np.array_equal(t.position, first.position, equal_nan=True) for t in others)
    print(f"  the same tracks each time: {same}")


def replay(run_dir: Path, config, threads) -> None:
    task = get_task(config.task)
    jobs, gaze = replay_stage._replay_jobs(run_dir, config, task.replays)
    for k, (p, seed) in enumerate(jobs):
        timed(f"replay: replay {k} alone",
              lambda p=p, seed=seed: replay_stage._physics(task, p, config, gaze, seed))
    walls = [0.0] * len(jobs)

    def one(k):
        start = time.perf_counter()
        replay_stage._physics(task, jobs[k][0], config, gaze, jobs[k][1])
        walls[k] = time.perf_counter() - start

    workers = min(len(jobs), os.cpu_count() or 1)
    with ThreadPoolExecutor(workers) as pool:
        timed(f"replay: all {len(jobs)} in {workers} threads (the stage)",
              lambda: list(pool.map(one, range(len(jobs)))))
    print("  each one's wall time there [s]: " + ", ".join(f"{w:.2f}" for w in walls))


def video(run_dir: Path, config, threads) -> None:
    states = ReplayFile.load(run_dir)  # the replay and the weight-0 one
    plan = PlanFile.load(run_dir)
    observations = ObservationsFile.load(run_dir).observations
    before = figures.VIDEO_THREADS
    try:
        for n in threads:
            figures.VIDEO_THREADS = n
            timed(f"video: its frames in {n} thread(s)",
                  lambda: sum(1 for _ in figures._video_frames(config, states, observations, plan)))
    finally:
        figures.VIDEO_THREADS = before


PARTS = {"observe": observe, "replay": replay, "video": video}
STAGES = ("observe", "learn", "optimize", "replay", "figures")


def load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def stages(repeat: int, quick: bool) -> None:
    """``imitate run`` ``repeat`` times in child processes (in a temporary folder, so that
    ``PYTHONPATH`` or the installed package decides which ``imitate``); the table of its stage
    timings."""
    with tempfile.TemporaryDirectory(prefix="bench_stages-") as tmp:
        where = subprocess.run(
            [sys.executable, "-c", "import imitate; print(imitate.__file__)"],
            capture_output=True, text=True, check=True, cwd=tmp,
        ).stdout.strip()
        subprocess.run([sys.executable, "-m", "imitate.warmup"], check=True, cwd=tmp,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        before, timings, frames = load(), {stage: [] for stage in STAGES}, []
        for k in range(repeat):
            out = Path(tmp, f"run{k}")
            log = Path(tmp, f"run{k}.log")
            with open(log, "w") as stderr:
                done = subprocess.run(
                    [sys.executable, "-m", "imitate", "run", "--out", str(out),
                     *(["--quick"] if quick else [])],
                    check=False, stdout=subprocess.DEVNULL, stderr=stderr, cwd=tmp,
                )
            if done.returncode:
                sys.exit(f"imitate run failed ({done.returncode}):\n{log.read_text()[-2000:]}")
            report = json.loads((out / "report.json").read_text())
            for stage in STAGES:
                timings[stage].append(report["timings"][stage])
            frames.append(report["video"]["frames"])
    seconds = {stage: statistics.median(t) for stage, t in timings.items()}
    total = sum(seconds.values())
    print(f"imitate run{' --quick' if quick else ''} ({where}), {repeat} time(s); "
          f"{os.cpu_count()} cores; load average before {before}, after {load()}")
    print(f"{'stage':<10} {'seconds':>8}" + ("   each run" if repeat > 1 else ""))
    for stage in STAGES:
        each = "   " + " ".join(f"{t:.1f}" for t in timings[stage]) if repeat > 1 else ""
        print(f"{stage:<10} {seconds[stage]:8.1f}{each}")
    print(f"{'total':<10} {total:8.1f}")
    print(f"figures' share {seconds['figures'] / total:.0%} (video {frames[0]} frames)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("run_dir", nargs="?", type=Path, default=Path("runs/latest"),
                        help="with --parts: the run measured (default runs/latest)")
    parser.add_argument("--parts", nargs="+", choices=list(PARTS),
                        help="measure these parts of RUN_DIR's stages instead of a whole run")
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2, 4],
                        help="the video's thread counts (--parts video)")
    parser.add_argument("--repeat", type=int, default=1, help="runs of the stages (median)")
    parser.add_argument("--quick", action="store_true", help="imitate run --quick")
    args = parser.parse_args()
    if min(args.threads) < 1 or args.repeat < 1:
        parser.error(f"--threads {args.threads} / --repeat {args.repeat} not accepted: counts "
                     "of at least 1")
    if not args.parts:
        stages(args.repeat, args.quick)
        return
    config = load_config(args.run_dir)
    print(f"{args.run_dir}; {os.cpu_count()} cores, load average {load()}")
    print(f"{'part':56s} {'wall [s]':>8s} {'cpu [s]':>8s}")
    for part in args.parts:
        PARTS[part](args.run_dir, config, args.threads)


if __name__ == "__main__":
    main()
