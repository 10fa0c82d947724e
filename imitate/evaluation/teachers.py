"""Teachers as a dimension of an evaluation: the learned models of several teacher seeds.

A run's learned model is one teacher's (its ``seed``). Teacher ``s`` is the same run with seed
``s``: the teacher demonstrates anew, the robot watches and learns with the run's settings.
Each is a run directory of its own, ``<out>/teachers/seed-<s>/``, made by the ``observe``,
``learn``, ``optimize`` and ``replay`` stages under its lock (the teacher's default run, but its
figures), so that an evaluation that stops keeps the teachers it has learned, and one that starts
again reuses every stage whose outputs' provenance still holds (see
:mod:`imitate.stages.provenance`)
and that the same code made (``code.json``: a change of the teacher's script, say, changes what
it demonstrates); the run's own seed is the run's ``model.npz`` and ``report.json``.
"""

from __future__ import annotations

import dataclasses
import logging
import os
from collections.abc import Sequence
from pathlib import Path

from imitate.envs import tasks
from imitate.errors import ImitateError
from imitate.run import load_run
from imitate.rundir import layout
from imitate.rundir.artifacts import load_json, refuse_link, save_json
from imitate.rundir.lock import locked
from imitate.stages import provenance, table
from imitate.stages.config import RunConfig, load_config
from imitate.stages.files import Learned, ModelFile

__all__ = ["MAX_TEACHERS", "Teacher", "check_model", "check_run", "run_task", "teacher_seeds",
           "teachers"]

log = logging.getLogger(__name__)

MAX_TEACHERS = 100
CODE = layout.CODE  # the code digest the teacher's stages ran with


@dataclasses.dataclass(frozen=True, eq=False)
class Teacher:
    """One teacher's learned model.

    Attributes:
        seed: The teacher's seed (the run's ``seed`` setting it was learned with).
        path: Its ``model.npz``.
        learned: The learned model and its gaze frame.
        model_bytes: The file's bytes (what an evaluation's digest is taken of).
        default_run: The ``replay`` section of its run's ``report.json`` (its default scene
            reproduced in physics), ``None`` if the run has none.
    """

    seed: int
    path: Path
    learned: Learned
    model_bytes: bytes
    default_run: dict | None

    @property
    def digest_bytes(self) -> bytes:
        """What its records depend on: the model's bytes, and its measured importance where
        it plans with one."""
        importance = self.learned.importance
        return self.model_bytes + (b"" if importance is None else importance.tobytes())


def teacher_seeds(run_seed: int, n: int) -> tuple[int, ...]:
    """The seeds of ``n`` teachers: the run's own first, then the next ones.

    Raises:
        ImitateError: ``n`` outside 1..:data:`MAX_TEACHERS`.
    """
    if not 1 <= n <= MAX_TEACHERS:
        raise ImitateError(f"--teachers {n} not accepted: a whole number in 1..{MAX_TEACHERS}")
    return tuple(run_seed + i for i in range(n))


def check_run(run_dir: Path | str) -> Path:
    """``run_dir`` as a path, if it is a directory (nothing is written into one that is not).

    Raises:
        ImitateError: it is not (:func:`imitate.run.load_run`'s message).
    """
    return load_run(run_dir).path


def check_model(run_dir: Path) -> None:
    """Refuse a run whose ``model.npz`` does not follow from its ``config.json`` and the files
    before it, as the stage that reads it does (a folder of a ``model.npz`` alone: nothing to
    check). Call it holding the run's lock.

    Raises:
        ImitateError: the first stage at fault, named with the command that re-runs it.
    """
    if not (run_dir / layout.CONFIG).exists():
        return
    config = load_config(run_dir)
    problems = provenance.stale(run_dir, table.find("optimize"), config, provenance.load(run_dir))
    if problems:
        raise ImitateError(f"{problems[0]} before evaluating its model")


def run_task(run_dir: Path | str) -> str:
    """The name of the task of the run in ``run_dir``: its ``config.json``'s, or the default
    task for a folder of a ``model.npz`` alone.

    Raises:
        ImitateError: ``run_dir`` is no directory (:func:`check_run`), or its ``config.json``
            is unusable.
    """
    run_dir = check_run(run_dir)
    if not (run_dir / layout.CONFIG).exists():
        return tasks.DEFAULT
    return load_config(run_dir).task


def teachers(
    run_dir: Path, out: Path, n: int, more: Sequence[int] = (), workers: int = 1
) -> list[Teacher]:
    """The learned models of ``n`` teachers for the run in ``run_dir`` (see the module), then
    of the teachers of the seeds ``more`` (none of the first ``n``): learned under
    ``out/teachers/`` where missing or stale, else read; several at once in up to ``workers``
    spawned processes (each teacher's stages in one, its own progress not shown).

    Raises:
        ImitateError: the run has no usable ``config.json`` or ``model.npz``, a folder of a
            teacher's run is a symbolic link, or a teacher's stage fails (its directory is left
            as it was).
    """
    run_dir = Path(run_dir)
    # the run's own model needs no settings (a folder of a model.npz alone is evaluated too)
    several = n > 1 or bool(more)
    config = load_config(run_dir) if several or (run_dir / "config.json").exists() else None
    own = config.seed if config else 0
    seeds = teacher_seeds(own, n)
    if set(seeds) & set(more):
        raise ImitateError(
            f"teacher seeds {sorted(set(seeds) & set(more))} both among the {n} teachers and "
            "the further ones; give fewer --teachers"
        )
    found = [_read(own, run_dir / layout.MODEL)]
    others = (*seeds[1:], *more)
    folders = [Path(out) / "teachers" / f"seed-{seed}" for seed in others]
    for folder in folders:
        inside = os.path.abspath(folder).startswith(os.path.abspath(run_dir) + os.sep)
        refuse_link(folder, run_dir if inside else out)  # eval/, teachers/, seed-S/
    jobs = [(folder, dataclasses.replace(config, seed=seed))
            for seed, folder in zip(others, folders, strict=True) if config is not None]
    if workers > 1 and len(jobs) > 1:
        _prepare_in_processes(jobs, workers)
    for job in jobs:
        _prepare(*job)  # (the ones learned in processes: read, all fresh)
    return [*found, *(_read(seed, f / layout.MODEL) for seed, f in zip(others, folders,
                                                                        strict=True))]


def _prepare_in_processes(jobs: list[tuple[Path, RunConfig]], workers: int) -> None:
    """:func:`_prepare` of every job, ``workers`` at once in spawned processes (MuJoCo's
    rendering and fork do not mix), each quiet, a progress bar over them. A failed teacher is
    left for the caller's own :func:`_prepare`, which raises its error."""
    import multiprocessing

    from imitate.stages.progress import bar

    stale = [job for job in jobs if _first_stale(*job) is not None]
    if len(stale) < 2:
        return
    log.info("teachers: learning %d in %d processes", len(stale), min(workers, len(stale)))
    context = multiprocessing.get_context("spawn")
    with context.Pool(min(workers, len(stale)), initializer=_quiet) as pool, bar(
        total=len(stale), desc="teachers", unit="teacher"
    ) as progress:
        for seed in pool.imap_unordered(_prepare_quietly, stale):
            progress.set_postfix(seed=seed)
            progress.update()


# The stages of a teacher's run, each with the next one, whose input check covers its outputs.
_STAGES = (("observe", "learn"), ("learn", "optimize"), ("optimize", "replay"),
           ("replay", "figures"))


def _prepare(folder: Path, config: RunConfig) -> None:
    """Run the teacher's stages in ``folder`` from the first whose outputs are missing or do not
    follow from ``config`` and the outputs before them."""
    from imitate.stages.runner import run_stage  # the stages' code: only where a teacher is learned

    folder.parent.mkdir(parents=True, exist_ok=True)
    command = f"imitate eval (teacher seed {config.seed})"
    with locked(folder, command, create=True):
        first = _first_stale(folder, config)
        if first is None:
            return
        for later, _ in _STAGES[first:]:
            log.info("teacher seed %d: %s", config.seed, later)
            run_stage(later, folder, config)
        save_json(folder / CODE, {"code": provenance.code_digest()})


def _first_stale(folder: Path, config: RunConfig) -> int | None:
    """The index in :data:`_STAGES` of the teacher's first stage in ``folder`` whose outputs are
    missing or do not follow from ``config`` and this code; ``None`` if none."""
    same_code = (folder / CODE).is_file() and _json(folder / CODE) == {
        "code": provenance.code_digest()
    }
    return next((i for i, (name, reader) in enumerate(_STAGES)
                 if not (same_code and _fresh(folder, name, reader, config))), None)


def _quiet() -> None:
    """A teacher process: no progress, no stage lines, Ctrl-C left to the parent."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    os.environ.setdefault("MUJOCO_GL", "egl")
    logging.getLogger("imitate").setLevel(logging.WARNING)


def _prepare_quietly(job: tuple[Path, RunConfig]) -> int:
    """:func:`_prepare` in a teacher process; its seed. Its errors are its caller's to find."""
    try:
        _prepare(*job)
    except ImitateError:
        pass
    return job[1].seed


def _json(path: Path):
    try:
        return load_json(path)
    except ImitateError:
        return None


def _fresh(folder: Path, name: str, reader: str, config: RunConfig) -> bool:
    """Whether stage ``name``'s outputs in ``folder`` are there and follow from ``config`` (as
    stage ``reader``, which reads them, checks its inputs)."""
    written = [f for f in table.find(name).writes if f != layout.CONFIG]
    if not all((folder / f).is_file() for f in written):
        return False
    try:
        manifest = provenance.load(folder)
        return not provenance.stale(folder, table.find(reader), config, manifest)
    except ImitateError:
        return False


def _read(seed: int, path: Path) -> Teacher:
    learned = ModelFile.load_learned(path.parent)
    report_path = path.parent / layout.REPORT
    report = load_json(report_path) if report_path.is_file() else {}
    default_run = report.get("replay") if isinstance(report, dict) else None
    return Teacher(seed, path, learned, path.read_bytes(), default_run)
