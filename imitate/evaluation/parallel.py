"""Variations in parallel: local worker processes or Ray tasks, results yielded as they finish.

A job is a variation, the teacher whose learned model reproduces it and the digest its record
is filed under; every job of a call is of one task. Each record depends on
its teacher's model and the variation's settings alone (``Trial.run`` seeds everything from
them), so the two back-ends and any number of workers give the same records, timings aside.
Local workers are spawned, not forked (MuJoCo's rendering contexts and fork do not mix), set
``MUJOCO_GL``, run single-threaded BLAS unless told otherwise, and exit by themselves when the
evaluation's process is killed (on Linux killed with it, elsewhere within 0.2 s).
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Generator, Sequence
from typing import Any

from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.evaluation.trial import Trial
from imitate.evaluation.variation import Variation
from imitate.stages.files import Learned

__all__ = ["Job", "run_local", "run_ray"]

# Thread counts of the numerical libraries in each worker: one, the workers fill the cores.
_SINGLE_THREAD = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
_worker: dict = {}  # a local worker's trials by teacher, set once by _start
_PARENT_POLL = 0.2  # [s] how often a local worker checks that its parent still runs
_PR_SET_PDEATHSIG = 1  # prctl's option (linux/prctl.h)

Job = tuple[str, int, Variation]  # (digest, teacher seed, variation)
Models = dict[int, Learned]  # the learned model and its gaze frame by teacher seed


def run_local(
    models: Models, jobs: Sequence[Job], workers: int, task: str
) -> Generator[dict[str, Any], None, None]:
    """Records of ``jobs`` (variations of the task named ``task``) from ``workers`` spawned
    processes (:class:`~imitate.evaluation.record.TrialRecord`), in the order they finish,
    each after its ``digest`` and ``teacher``; ``models``: each teacher's learned model. If
    the caller stops (Ctrl-C, an error, closing the iterator), the workers are terminated at
    once: Ctrl-C reaches this process only."""
    for name in _SINGLE_THREAD:  # inherited by the spawned workers
        os.environ.setdefault(name, "1")
    context = multiprocessing.get_context("spawn")
    pool = context.Pool(workers, initializer=_start, initargs=(models, task))
    try:
        yield from pool.imap_unordered(_run, [(d, t, v.to_json()) for d, t, v in jobs])
        pool.close()
    finally:
        pool.terminate()
        pool.join()


def run_ray(
    models: Models, jobs: Sequence[Job], address: str, task: str
) -> Generator[dict[str, Any], None, None]:
    """As :func:`run_local`, one Ray task (one CPU) per variation, on the Ray instance this
    process is connected to, or else on the cluster at ``address`` (``"auto"``: the one Ray
    finds). The workers need ``imitate`` installed.

    Raises:
        ImitateError: Ray is not installed, or no cluster answers at ``address``.
    """
    try:
        import ray
    except ImportError:
        raise ImitateError(
            "--ray needs Ray, which is not installed: pip install 'imitate-humanoid[ray]'"
        ) from None
    if not ray.is_initialized():
        try:
            ray.init(address=address, log_to_driver=False)
        except (ConnectionError, RuntimeError, ValueError) as err:
            raise ImitateError(f"no Ray cluster at --ray {address}: {err}") from None
    remote = ray.remote(num_cpus=1)(_run_with)
    shared = {teacher: ray.put(learned) for teacher, learned in models.items()}
    pending = [remote.remote(shared[t], task, d, t, v.to_json()) for d, t, v in jobs]
    try:
        while pending:
            done, pending = ray.wait(pending, num_returns=1)
            yield ray.get(done[0])
    finally:
        for ref in pending:
            ray.cancel(ref)


def _start(models: Models, task: str) -> None:
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    parent = os.getppid()
    if not _killed_with_parent() or os.getppid() != parent:
        threading.Thread(target=_exit_with, args=(parent,), daemon=True).start()
    os.environ.setdefault("MUJOCO_GL", "egl")
    found = get_task(task)
    _worker.update({teacher: Trial(learned, found) for teacher, learned in models.items()})


def _killed_with_parent() -> bool:
    """Ask Linux to SIGKILL this worker when the thread that started it (the evaluation's main
    thread) ends, killed or not: at once, before its record could meet a closed pipe. Whether
    it could (not elsewhere: :func:`_exit_with` polls there)."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0) == 0
    except (OSError, AttributeError):
        return False


def _exit_with(parent: int) -> None:
    """Exit this worker at once when its ``parent`` is gone (killed: nobody reads its record,
    and nobody terminates it), checking every :data:`_PARENT_POLL` seconds."""
    while os.getppid() == parent:
        time.sleep(_PARENT_POLL)
    os._exit(1)


def _run(job: tuple[str, int, dict]) -> dict[str, Any]:
    digest, teacher, variation = job
    record = _worker[teacher].run(Variation.from_json(variation))
    return {"digest": digest, "teacher": teacher, **record}


def _run_with(
    learned: Learned, task: str, digest: str, teacher: int, variation: dict
) -> dict[str, Any]:
    """A Ray task: one variation of the task named ``task`` with the ``learned`` model (a Ray
    worker may serve several evaluations, so nothing is kept)."""
    os.environ.setdefault("MUJOCO_GL", "egl")
    record = Trial(learned, get_task(task)).run(Variation.from_json(variation))
    return {"digest": digest, "teacher": teacher, **record}
