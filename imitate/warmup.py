"""The numba kernels, compiled ahead of a run (``python -m imitate.warmup``) or announced as
a stage compiles them.

numba compiles a kernel the first time a process calls it and keeps the machine code in its
on-disk cache (``cache=True``): later processes load it in milliseconds. ``make setup`` runs
this module once after installing, so that the first ``imitate run`` finds every kernel in the
cache. It runs the tracker on one rendered stereo pair, the learner on a few short synthetic
demonstrations and one planner iteration, the code paths of a run with the argument types of a
run, in two processes at once (numba compiles on one core): the tracker's and the planner's
kernels in one, the learner's (DTW, K-means, EM, BIC) in the other. Between them they compile
every kernel a run calls (a warm run compiles nothing: ``scripts/bench/bench_run.py`` shows it);
with one process, all of it runs here, one after the other.

:func:`announce_compiles` makes a process say on stderr which kernel it compiles, so that a
stage that compiles for seconds is not silent.
"""

from __future__ import annotations

import sys
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import numpy as np

__all__ = ["announce_compiles", "warm"]

_ANNOUNCING: list = []  # the listener, once registered


def announce_compiles(stream=None) -> None:
    """From now on, print a line on ``stream`` (stderr) when numba starts compiling one of
    imitate's kernels (not when it loads one from its cache); once per process."""
    if _ANNOUNCING:
        return
    from numba.core import event

    from imitate import numba_cache

    numba_cache.said()  # this announcer names every kernel

    stream = stream or sys.stderr

    class Announcer(event.Listener):
        def on_start(self, ev):
            function = ev.data["dispatcher"].py_func
            if function.__module__.startswith("imitate"):
                name = f"{function.__module__}.{function.__qualname__}"
                _write(f"numba: compiling {name} (once; later runs load it from the cache)",
                       stream)

        def on_end(self, ev):
            pass

    _ANNOUNCING.append(Announcer())
    event.register("numba:compile", _ANNOUNCING[0])


def _write(line: str, stream) -> None:
    try:  # above a progress bar, if one is showing
        from tqdm import tqdm

        tqdm.write(line, file=stream)
    except ImportError:  # pragma: no cover - tqdm is a dependency
        print(line, file=stream, flush=True)


def _tracker() -> None:
    """The tracker's kernels (steps 3-5) on one rendered stereo pair of a small session."""
    import dataclasses

    from imitate.envs.observation import ObservationConfig, frames, session
    from imitate.envs.teacher_motion import TeacherConfig
    from imitate.perception import StereoTracker, perception_config
    from imitate.perception.watch import cameras

    sess = session(ObservationConfig(teacher=TeacherConfig(n_demos=2), width=320, height=240))
    start, end = sess.motion.boundaries[0]
    sess = dataclasses.replace(sess, times=sess.times[sess.times >= 0.5 * (start + end)][:1])
    tracker = StereoTracker(*cameras(sess), perception_config())
    for left, right in frames(sess, ahead=False):
        tracker.update(left, right)


def _demos():
    from imitate.demos.synthetic import SyntheticConfig, pouring_demos

    synthetic = pouring_demos(SyntheticConfig(n_demos=3, duration=1.0, rate=40.0))
    return synthetic.demos, synthetic.rate


def _learning_em() -> None:
    """DTW, EM from K-means starts (the full BIC) and GMR, as ``learn`` runs them."""
    from imitate.learning import LearningConfig, learn

    demos, rate = _demos()
    learn(demos, rate=rate, config=LearningConfig(k_max=4, bic_method="full"))


def _learning_kmeans() -> None:
    """K-means chains and the fast BIC."""
    from imitate.learning import time_stacked
    from imitate.learning.bic import bic_sweep

    demos, rate = _demos()
    bic_sweep(time_stacked(demos, rate), 4, "fast")


def _planner() -> None:
    """One iteration of the planner (task map, RMR, near-pair bounds, adjoint) on the robot, from
    a two-component model of a short synthetic demonstration."""
    from imitate.learning import LearnedModel
    from imitate.learning.gmm import GMM
    from imitate.models import humanoid
    from imitate.motion import PlanConfig, plan_from_model
    from imitate.motion.replay import planning_task

    demos, rate = _demos()
    mean = demos[0]
    times = np.arange(len(mean)) / rate
    data = np.column_stack((times, mean))
    halves = np.array_split(data, 2)
    gmm = GMM.from_parameters(
        np.full(2, 0.5), np.array([h.mean(axis=0) for h in halves]),
        np.array([np.cov(h.T) + 1e-3 * np.eye(data.shape[1]) for h in halves]),
    )
    covariance = np.broadcast_to(1e-4 * np.eye(mean.shape[1]), (len(mean),) + (mean.shape[1],) * 2)
    model = LearnedModel(data, gmm, np.empty(0), times, mean, covariance.copy(), None)
    plan_from_model(planning_task(), model, q0=humanoid.rest_pose(), config=PlanConfig(max_iter=1))


def _everything() -> None:
    """What a run calls: the tracker, and the learner with both BICs and without DTW."""
    import dataclasses

    from imitate.learning import LearningConfig, learn

    _tracker()
    _planner()
    demos, rate = _demos()
    for method in ("full", "fast"):
        config = LearningConfig(k_max=4, bic_method=method)
        learn(demos, rate=rate, config=config)
        learn(demos, rate=rate, config=dataclasses.replace(config, n_components=2, use_dtw=False))


_GROUPS = {  # the full BIC runs K-means too: the learner's kernels in one group
    "tracker, planner": (_tracker, _planner),
    "DTW, K-means, EM, BIC": (_learning_em, _learning_kmeans),
}


def _group(name: str) -> float:
    """Compile the kernels of group ``name`` (in a worker process); returns the seconds."""
    announce_compiles()
    start = time.perf_counter()
    for step in _GROUPS[name]:
        step()
    return time.perf_counter() - start


def warm(processes: int = 2, stream=None) -> float:
    """Compile (or load) every kernel a run calls; returns the seconds it took.

    Args:
        processes: compile the two groups of kernels in this many processes at once (spawned;
            1 or less: here, one after the other, with every variant of the learner).
        stream: where to report (stderr).
    """
    stream = stream or sys.stderr
    start = time.perf_counter()
    print("numba: compiling the tracker's, the learner's and the planner's kernels into the "
          "cache ...",
          file=stream, flush=True)
    announce_compiles(stream)
    if processes > 1:
        context = get_context("spawn")
        with ProcessPoolExecutor(min(processes, len(_GROUPS)), mp_context=context) as pool:
            for name, seconds in zip(_GROUPS, pool.map(_group, _GROUPS), strict=True):
                print(f"numba: {name} kernels ready after {seconds:.1f} s", file=stream,
                      flush=True)
    else:
        _everything()
    seconds = time.perf_counter() - start
    print(f"numba: kernels ready in {seconds:.1f} s", file=stream, flush=True)
    return seconds


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--processes", type=int, default=2,
                        help="compile in this many processes at once (default 2)")
    warm(parser.parse_args().processes)
