"""The observation stage's rendering and tracking, with the pairs rendered ahead in a thread or
in the tracking thread.

    python scripts/bench/bench_observe.py [--pairs 240] [--repeats 2]

Renders the first ``--pairs`` stereo pairs of the default session (640x480, 30 Hz) and tracks
them, once rendered in the tracking thread pair by pair (``frames(..., ahead=False)``) and once
rendered ahead by a thread while this one tracks (the default), the two interleaved
``--repeats`` times. Every setting's tracks must equal, bit for bit, those of the first; the
table shows the wall time (the render thread's start-up included), the pairs per second, the
processor time (all threads), the rendering time and the tracking time, and the load average
(the machine may be shared).
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import resource
import time

import numpy as np

from imitate.envs.observation import ObservationConfig, frames, session
from imitate.perception import StereoTracker, perception_config, track
from imitate.perception.watch import cameras


def run(sess, ahead: bool) -> tuple[dict, object]:
    timing: dict = {}
    cpu = cpu_seconds()
    start = time.perf_counter()
    tracker = StereoTracker(*cameras(sess), perception_config(sess.motion.objects))
    tracks = track(tracker, frames(sess, timing, ahead=ahead), sess.times, timing)
    timing["wall"] = time.perf_counter() - start
    timing["cpu"] = cpu_seconds() - cpu
    return timing, tracks


def cpu_seconds() -> float:
    """User and system time of this process, all threads [s]."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def same(a, b) -> bool:
    return all(
        np.array_equal(getattr(a, name), getattr(b, name), equal_nan=True)
        for name in ("position", "axis", "angle", "detected")
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=240)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=480)
    args = parser.parse_args()
    config = ObservationConfig(width=args.width, height=args.height)
    sess = session(config)
    sess = dataclasses.replace(sess, times=sess.times[: args.pairs])
    # One untimed pass: the tracker's compiled loops are compiled or loaded once per process.
    run(dataclasses.replace(sess, times=sess.times[:2]), False)
    print(f"{len(sess.times)} pairs {args.width}x{args.height}, {os.cpu_count()} cores")
    print(f"{'rendered':<22}{'wall':>7}{'pairs/s':>9}{'cpu':>7}{'render':>8}{'track':>7}"
          f"  identical  load average")
    print(f"{'':<22}{'[s]':>7}{'':>9}{'[s]':>7}{'[s]':>8}{'[s]':>7}")
    reference = None
    for _ in range(args.repeats):
        for ahead in (False, True):
            timing, tracks = run(sess, ahead)
            reference = reference or tracks
            label = "ahead, in a thread" if ahead else "in the tracking thread"
            print(
                f"{label:<22}{timing['wall']:7.2f}{len(sess.times) / timing['wall']:9.1f}"
                f"{timing['cpu']:7.2f}{timing['render']:8.2f}{timing['track']:7.2f}"
                f"  {str(same(tracks, reference)):<9}  "
                + " ".join(f"{v:.2f}" for v in os.getloadavg()),
                flush=True,
            )


if __name__ == "__main__":
    main()
