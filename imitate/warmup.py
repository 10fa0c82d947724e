"""The numba kernels: the one list of their modules, compiled ahead of a run (``python -m
imitate.warmup``) or announced as a stage compiles them.

numba compiles a kernel the first time a process calls it and keeps the machine code in its
on-disk cache (``cache=True``): later processes load it in milliseconds. ``make setup`` runs
this module once after installing (the Makefile's stamp depends on the files of
:data:`KERNELS`), so that the first ``imitate run`` finds every kernel in the cache. For each
stage of :data:`KERNELS` it runs that stage's code path with the argument types of a run: the
tracker on one rendered stereo pair, the learner on a few short synthetic demonstrations, one
planner iteration; the stages in two processes at once (numba compiles on one core), the
longest first. Each then checks that it reached every kernel of its stage's modules (a warm run
compiles nothing: ``scripts/bench/bench_run.py`` shows it).

:func:`compile_notice` is the line the ``imitate`` command prints before a stage that compiles,
and :func:`announce_compiles` makes a process say on stderr which kernel it compiles, so that a
stage that compiles for seconds is not silent.
"""

from __future__ import annotations

import importlib
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from contextlib import ExitStack
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from imitate import _numba
from imitate.errors import ImitateError

__all__ = ["KERNELS", "KERNEL_MODULES", "announce_compiles", "compile_notice", "uncompiled",
           "warm"]

# The one list of numba-compiled kernel modules: by the stage that first compiles them, with
# about how long that takes on the 2-core CI machine [s] (`python scripts/bench/bench_run.py`).
# Each calls ensure_writable(__file__) before declaring its kernels; warm() compiles them all
# and the Makefile's warm-up stamp depends on their files (it reads them from this file).
KERNELS = {
    "observe": (("imitate.perception._rim", "imitate.perception._outline"), 4),
    "learn": (
        ("imitate.learning.dtw", "imitate.learning.kmeans", "imitate.learning._em",
         "imitate.learning.bic"),
        7,
    ),
    "optimize": (("imitate.motion._planner",), 10),
}
KERNEL_MODULES = tuple(name for names, _ in KERNELS.values() for name in names)

_ANNOUNCING: list = []  # the listener, once registered


def compile_notice(stage: str) -> str | None:
    """A line saying that ``stage`` compiles its kernels, else None: when numba's cache holds
    no kernel of one of its modules as declared now."""
    if stage not in KERNELS:
        return None
    modules, seconds = KERNELS[stage]
    uncached = set()
    for module in map(importlib.import_module, modules):
        if not _numba.cached(module):
            assert module.__file__ is not None  # the kernel modules are source files
            uncached.add(str(_numba.cache_dir(Path(module.__file__))))
    if not uncached:
        return None
    _numba.said()
    return (
        f"compiling the {stage} kernels once (about {seconds} s on two idle cores, several times "
        f"that on a busy machine); later runs load them from "
        f"the cache at {', '.join(sorted(uncached))}"
    )


def announce_compiles(stream=None) -> None:
    """From now on, print a line on ``stream`` (stderr) when numba starts compiling one of
    imitate's kernels (not when it loads one from its cache); once per process."""
    if _ANNOUNCING:
        return
    from numba.core import event

    _numba.said()  # this announcer names every kernel

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


def uncompiled(modules) -> list[str]:
    """The kernels of ``modules`` (names) that this process has neither called (compiled or
    loaded from the cache) nor reached from one it called: compiling a kernel compiles the
    kernels it calls, but loading it from the cache loads none of them."""
    missing = []
    for name in modules:
        declared = _numba.kernels(importlib.import_module(name))
        reached = {kernel for kernel, dispatcher in declared.items() if dispatcher.signatures}
        calling = list(reached)
        while calling:
            for called in declared[calling.pop()].py_func.__code__.co_names:
                if called in declared and called not in reached:
                    reached.add(called)
                    calling.append(called)
        missing += [f"{name}.{kernel}" for kernel in declared if kernel not in reached]
    return missing


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
    tracker = StereoTracker(*cameras(sess), perception_config(sess.motion.objects))
    for left, right in frames(sess, ahead=False):
        tracker.update(left, right)


def _demos():
    from imitate.demos.synthetic import SyntheticConfig, phased_demos

    synthetic = phased_demos(SyntheticConfig(n_demos=3, duration=1.0, rate=40.0))
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


# Each stage's code path, with the argument types of a run (the full BIC runs K-means too).
_PATHS = {
    "observe": (_tracker,),
    "learn": (_learning_em, _learning_kmeans),
    "optimize": (_planner,),
}


def _stage(stage: str) -> tuple[float, list[str]]:
    """Compile the kernels of ``stage`` (in a worker process); returns the seconds and the
    kernels of its modules that the code path did not reach (:func:`uncompiled`)."""
    announce_compiles()
    start = time.perf_counter()
    for path in _PATHS[stage]:
        path()
    return time.perf_counter() - start, uncompiled(KERNELS[stage][0])


def warm(processes: int = 2, stream=None) -> float:
    """Compile (or load) every kernel of :data:`KERNELS`; returns the seconds it took.

    Args:
        processes: run the stages' code paths in this many processes at once (spawned; 1 or
            less: here, one after the other).
        stream: where to report (stderr).

    Raises:
        ImitateError: a stage's code path does not reach every kernel of its modules.
    """
    stream = stream or sys.stderr
    start = time.perf_counter()
    stages = sorted(KERNELS, key=lambda stage: -KERNELS[stage][1])  # the longest first
    print(f"numba: compiling the kernels of {', '.join(stages)} into the cache ...",
          file=stream, flush=True)
    announce_compiles(stream)
    missing = []
    with ExitStack() as workers:
        if processes > 1:
            pool = ProcessPoolExecutor(min(processes, len(stages)), mp_context=get_context("spawn"))
            done = workers.enter_context(pool).map(_stage, stages)
        else:
            done = map(_stage, stages)
        for stage, (seconds, left) in zip(stages, done, strict=True):
            print(f"numba: {stage} kernels ready after {seconds:.1f} s", file=stream, flush=True)
            missing += left
    if missing:
        raise ImitateError(
            f"the warm-up compiles not every kernel: its code paths (imitate.warmup._PATHS) "
            f"reach none of {', '.join(missing)}"
        )
    seconds = time.perf_counter() - start
    print(f"numba: kernels ready in {seconds:.1f} s", file=stream, flush=True)
    return seconds


if __name__ == "__main__":
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--processes", type=int, default=2,
                        help="compile in this many processes at once (default 2)")
    warm(parser.parse_args().processes)
