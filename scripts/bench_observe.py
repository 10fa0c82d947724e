"""The observation stage's rendering and tracking, in this process or with render workers.

    python scripts/bench_observe.py [--pairs 240] [--repeats 2] [--workers 0 1 2]

Renders the first ``--pairs`` stereo pairs of the default session (640x480, 30 Hz) and tracks
them, once per setting of ``render_workers`` (0: render here, then track, pair by pair; N >= 1:
N spawned processes render while this one tracks), the settings interleaved ``--repeats``
times. ``LP_NUM_THREADS=1`` rows limit Mesa's rasterizer threads of the workers to one each.
Every setting's tracks must equal, bit for bit, those of the first; the table shows the wall
time (worker start-up included), the pairs per second, the processor time of this process and
its workers (all threads), the rendering time (summed over the workers), the time this
process waited for frames and tracked, and the load average (the machine may be shared).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import resource
import time

import numpy as np

from imitate.envs.observation import ObservationConfig, frames, session
from imitate.observe import cameras
from imitate.perception import StereoTracker, perception_config, track


def run(sess, workers: int, lp_threads: str | None) -> tuple[dict, object]:
    previous = os.environ.get("LP_NUM_THREADS")
    if lp_threads is not None:
        os.environ["LP_NUM_THREADS"] = lp_threads  # read by the workers' Mesa at start-up
    try:
        timing: dict = {}
        cpu = cpu_seconds()
        start = time.perf_counter()
        tracker = StereoTracker(*cameras(sess), perception_config())
        tracks = track(tracker, frames(sess, timing, workers=workers), sess.times, timing)
        timing["wall"] = time.perf_counter() - start
        timing["cpu"] = cpu_seconds() - cpu
    finally:
        if previous is None:
            os.environ.pop("LP_NUM_THREADS", None)
        else:
            os.environ["LP_NUM_THREADS"] = previous
    return timing, tracks


def cpu_seconds() -> float:
    """User and system time of this process (all threads) and its waited-for children [s]."""
    return sum(
        usage.ru_utime + usage.ru_stime
        for usage in map(resource.getrusage, (resource.RUSAGE_SELF, resource.RUSAGE_CHILDREN))
    )


def same(a, b) -> bool:
    return all(
        np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True)
        for name in ("position", "axis", "angle", "detected")
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=240)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--workers", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    args = parser.parse_args()
    config = ObservationConfig(width=args.width, height=args.height)
    sess = session(config)
    sess = dataclasses.replace(sess, times=sess.times[: args.pairs])
    settings = [(w, None) for w in args.workers] + [
        (w, "1") for w in args.workers if w >= 2
    ]
    # One untimed pass: the tracker's compiled loops are compiled or loaded once per process.
    run(dataclasses.replace(sess, times=sess.times[:2]), 0, None)
    print(f"{len(sess.times)} pairs {args.width}x{args.height}, {os.cpu_count()} cores")
    print(f"{'render workers':<26}{'wall':>7}{'pairs/s':>9}{'cpu':>7}{'render':>8}{'wait':>7}"
          f"{'track':>7}  identical  load average")
    print(f"{'':<26}{'[s]':>7}{'':>9}{'[s]':>7}{'[s]':>8}{'[s]':>7}{'[s]':>7}")
    reference = None
    for _ in range(args.repeats):
        for workers, lp_threads in settings:
            timing, tracks = run(sess, workers, lp_threads)
            reference = reference or tracks
            label = f"{workers}" + (f" (LP_NUM_THREADS={lp_threads})" if lp_threads else "")
            print(
                f"{label:<26}{timing['wall']:7.2f}{len(sess.times) / timing['wall']:9.1f}"
                f"{timing['cpu']:7.2f}"
                f"{timing['render']:8.2f}{timing.get('wait', 0.0):7.2f}{timing['track']:7.2f}"
                f"  {str(same(tracks, reference)):<9}  "
                + " ".join(f"{v:.2f}" for v in os.getloadavg()),
                flush=True,
            )


if __name__ == "__main__":
    main()
