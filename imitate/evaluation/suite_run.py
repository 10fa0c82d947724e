"""``imitate eval``: learned models reproduced in the variations of a suite.

The models are the run's and, with ``teachers``, those of more teacher seeds
(:mod:`~imitate.evaluation.teachers`); each teacher reproduces every variation, drawn once per
teacher (its obstacles in the path are placed on that teacher's path, its shelves and plates
where that teacher's reproduction is in the task's critical phase). The run's task
(:func:`~imitate.evaluation.teachers.run_task`) is the suite's, and decides the scene, the
physics, the measures and the outcomes.

Writes under ``RUN_DIR/eval/<suite>-w<collision weight>-<similarity>/`` (:func:`default_out`;
or the folder ``out``), so that evaluations of another suite, weight or weighting keep theirs:
``results.jsonl`` (one record per
teacher and variation, appended and synced as each finishes, with its digest, the teacher's seed
and the exact settings), ``summary.json``, ``outcomes.png`` and ``report.html`` (of the last
evaluation), ``failures/<digest>/<id>-<outcome>.mp4`` for the first failures; the learned models
of the other teachers go to ``RUN_DIR/eval/teachers/``, whatever ``out``. An interrupted
evaluation continues where it stopped: a variation whose id already has a record under the same
digest (suite, seed, the teacher's learned model, the code) is not run again.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Collection, Iterator, Sequence
from contextlib import closing
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np

from imitate.envs import tasks
from imitate.envs.task import Task, get_task
from imitate.errors import ImitateError
from imitate.evaluation.parallel import Job, run_local, run_ray
from imitate.evaluation.record import (
    TrialRecord,
    change_keys,
    error_keys,
    is_number,
    score_keys,
)
from imitate.evaluation.report import failure_video, plot_outcomes, summarize, summarize_teachers
from imitate.evaluation.sensitivity import with_importance
from imitate.evaluation.suite import KEYS, Suite
from imitate.evaluation.teachers import Teacher, check_model, check_run, run_task, teachers
from imitate.evaluation.variation import CriticalPlace, Variation, draw, free_places
from imitate.figures import plots
from imitate.rundir import page
from imitate.rundir.artifacts import (
    check_regular,
    load_json,
    refuse_hard_link,
    refuse_link,
    save_bytes,
    save_json,
)
from imitate.rundir.lock import locked
from imitate.stages import provenance
from imitate.stages.progress import bar as progress_bar

__all__ = [
    "Draw", "check_counts", "check_folder", "check_task", "default_out", "draw_jobs",
    "evaluate", "last_records", "read_records", "run_jobs",
]

RESULTS = "results.jsonl"
# What an evaluation writes in its folder (the failure videos in failures/).
OUTPUTS = (RESULTS, "summary.json", "outcomes.png", "report.html", "failures")


def evaluate(
    run_dir: Path,
    suite: Suite,
    *,
    n: int | None = None,
    seed: int = 0,
    n_teachers: int = 1,
    workers: int | None = None,
    ray: str | None = None,
    videos: int = 3,
    progress: bool | None = None,
    out: Path | str | None = None,
    name: str = "default",
) -> dict:
    """Evaluate the learned models of ``n_teachers`` teachers of ``run_dir`` (the run's own
    first) on ``n`` variations of ``suite`` (default: its ``variations``) drawn with ``seed``, on
    ``workers`` local processes (default: every core) or on Ray (``ray``: an address or
    ``"auto"``); videos of the first ``videos`` failures; into ``out`` (default
    :func:`default_out` of ``run_dir``, the suite's ``name`` and its settings). ``progress``:
    a bar (``None``: on a terminal, else log lines; see :func:`~imitate.stages.progress.bar`).
    Returns the summary.

    Raises:
        ImitateError: a missing or corrupt model, a suite of another task than the run's,
            ``n``, ``workers`` or ``n_teachers`` out of range, Ray unusable, ``out`` refused
            (:func:`check_folder`), or another command holds the run directory (its lock, taken
            for the whole evaluation; not where nothing is written in a directory this user
            cannot write: ``out`` elsewhere, one teacher).
    """
    run_dir = check_run(run_dir)
    task = check_task(run_dir, suite)
    out = default_out(run_dir, name, suite) if out is None else Path(out)
    inside = os.path.abspath(out).startswith(os.path.abspath(run_dir) + os.sep)
    reading = not inside and n_teachers == 1  # nothing written in the run directory
    with locked(run_dir, f"imitate eval {run_dir}", reading=reading):
        n, workers = check_counts(suite, n, workers)
        check_model(run_dir)
        check_folder(out, run_dir)
        out.mkdir(parents=True, exist_ok=True)
        models = teachers(run_dir, run_dir / "eval", n_teachers, workers=workers)
        if suite["similarity"] == "importance":
            models = with_importance(run_dir, models)
        drawn = draw_jobs(models, suite, seed, n)
        records, run = run_jobs(out / RESULTS, drawn, models, workers, ray, progress, task)
        digests = [d.digest for d in drawn]
        ordered = [records[(d.digest, v.id)] for d in drawn for v in d.variations]
        summary = {
            "suite_digest": combined_digest(digests), "seed": seed, "task": task.name,
            "suite": suite.to_json(), "path_points": len(drawn[0].path),
            **summarize(ordered, task),
            "teachers": summarize_teachers(
                ordered, {d.teacher: d.digest for d in drawn},
                {t.seed: t.default_run for t in models}, task,
            ),
            "run": run,
        }
        save_json(out / "summary.json", summary)
        figure = plot_outcomes(ordered, drawn[0].path, task)
        save_bytes(out / "outcomes.png", plots.figure_png(figure))
        learned = {t.seed: t.learned for t in models}
        failures = [r for r in ordered if r["outcome"] != "success"][:videos]
        for record in progress_bar(failures, progress, desc="failure videos", unit="video"):
            name = f"{record['id']:04d}-{record['outcome']}.mp4"
            video = out / "failures" / record["digest"] / name
            refuse_link(video, out)
            if not video.exists():
                t = record["teacher"]
                failure_video(video, learned[t].model, learned[t].gaze, record,
                              learned[t].task(task))
        page.save_eval_page(out, summary, task.score.name)
        return summary


def check_task(run_dir: Path, suite: Suite) -> Task:
    """The task of the run in ``run_dir`` (:func:`run_task`), which must be ``suite``'s.

    Raises:
        ImitateError: a suite of another task.
    """
    name = run_task(run_dir)
    if suite.task != name:
        raise ImitateError(
            f"the suite is of task {suite.task!r}, the run in {run_dir} of task {name!r}: give "
            "a suite of the run's task"
        )
    return get_task(name)


def default_out(run_dir: Path, name: str, suite: Suite) -> Path:
    """The evaluation's folder unless told: ``run_dir/eval/<name>-w<collision_weight>-<similarity>``
    (e.g. ``eval/default-w10000-variance``), one per suite, weight and weighting."""
    return Path(run_dir) / "eval" / f"{name}-w{suite['collision_weight']:g}-{suite['similarity']}"


def check_folder(out: Path, run_dir: Path) -> None:
    """Refuse ``out`` as an evaluation's folder unless it is missing, empty or an
    evaluation's (a ``results.jsonl`` with records, or an evaluation's ``summary.json``, or,
    alone in it, a ``results.jsonl`` of no whole record but what an evaluation cut short in
    its first leaves: :func:`_cut_short`; not a hard link), and a real folder:
    no symbolic link in it or between it and ``run_dir`` when within it, no file in the way.

    Raises:
        ImitateError: one line naming the path and what to do.
    """
    out, run_dir = Path(out), Path(run_dir)
    inside = os.path.abspath(out).startswith(os.path.abspath(run_dir) + os.sep)
    refuse_link(out / RESULTS, run_dir if inside else out)
    for part in (out, *out.parents):
        if part.exists() and not part.is_dir():
            raise ImitateError(
                f"{part} is a file, in the way of the evaluation's folder {out}: remove it or "
                "give another --out"
            )
    results = out / RESULTS
    refuse_hard_link(results)
    ours = results.exists() and next(_records(results), None) is not None
    if not out.is_dir() or ours or _is_summary(out / "summary.json"):
        return
    names = sorted(entry.name for entry in out.iterdir())
    if names == [RESULTS] and _cut_short(results):
        return  # an evaluation's, cut short in its first record (it writes nothing else before)
    if names:
        more = f" and {len(names) - 3} more" if len(names) > 3 else ""
        raise ImitateError(
            f"{out} holds {', '.join(names[:3])}{more} but no evaluation (a {RESULTS} of its "
            "records, or the summary.json of one), and eval would replace files there; give a "
            "new or empty folder as --out"
        )


def _is_summary(path: Path) -> bool:
    """Whether ``path`` is an evaluation's ``summary.json`` (an object with its digest).

    Raises:
        ImitateError: it is there but no regular file (:func:`check_regular`).
    """
    check_regular(path)
    try:
        summary = json.loads(path.read_bytes()[:10_000_000])
    except (OSError, ValueError, RecursionError):
        return False
    return isinstance(summary, dict) and "suite_digest" in summary


@dataclass(frozen=True, eq=False)
class Draw:
    """One teacher's variations of a suite.

    Attributes:
        teacher: The teacher's seed.
        digest: Identifies its records (:meth:`Suite.digest` of the suite, the seed of the
            draw, the teacher's model and the code).
        path: ``(P, 3)`` points of its weight-0 path
            (:func:`~imitate.evaluation.variation.path_points`).
        variations: The variations, by id.
    """

    teacher: int
    digest: str
    path: np.ndarray
    variations: tuple[Variation, ...]


def draw_jobs(
    models: Sequence[Teacher], suite: Suite, seed: int, n: int,
    places: dict[int, tuple[np.ndarray, CriticalPlace]] | None = None,
) -> list[Draw]:
    """Variations ``0..n-1`` of ``suite`` drawn with ``seed`` for each teacher in ``models``
    (its path and critical place from one reproduction at collision weight 0:
    :func:`free_places`, kept in ``places`` by teacher seed if given, for the next suite of the
    same ``max_iter``)."""
    code, task = provenance.code_digest(), get_task(suite.task)
    places = {} if places is None else places
    drawn = []
    for t in models:
        if t.seed not in places:
            places[t.seed] = free_places(t.learned.planned, t.learned.gaze, suite["max_iter"],
                                         t.learned.task(task))
        path, place = places[t.seed]
        drawn.append(Draw(
            t.seed, suite.digest(seed, t.seed, t.digest_bytes, code), path,
            tuple(draw(suite, seed, i, path, place) for i in range(n)),
        ))
    return drawn


def run_jobs(
    results: Path,
    drawn: Sequence[Draw],
    models: Sequence[Teacher],
    workers: int,
    ray: str | None,
    progress: bool | None,
    task: Task,
) -> tuple[dict[tuple[str, int], TrialRecord], dict]:
    """Runs the variations of ``drawn`` (of ``task``) that have no record in ``results`` yet,
    appending each record as it finishes. Returns every record of ``drawn`` by ``(digest, id)``
    and the numbers of this call (``ran``, wall time, back-end, load average).

    Raises:
        ImitateError: ``results`` or its folder is a symbolic link.
    """
    refuse_link(results)
    refuse_hard_link(results)
    wanted = {d.digest for d in drawn}
    records = {
        (r["digest"], r["id"]): r for r in read_records(results, wanted, task)
    }
    pending = [
        (d, v) for d in drawn for v in d.variations if (d.digest, v.id) not in records
    ]
    jobs: list[Job] = [(d.digest, d.teacher, v) for d, v in pending]
    learned = {t.seed: t.learned for t in models if t.seed in {d.teacher for d in drawn}}
    total = sum(len(d.variations) for d in drawn)
    start, load = time.perf_counter(), os.getloadavg()
    no_records: tuple[dict, ...] = ()
    finished = (
        run_ray(learned, jobs, ray, task.name) if ray
        else run_local(learned, jobs, min(workers, len(jobs)), task.name)
    ) if jobs else (record for record in no_records)  # closable, as the workers' iterators
    _end_line(results)
    # closing: an interruption stops the workers before it propagates
    with closing(finished), open(results, "a") as f, progress_bar(
        show=progress, total=total, initial=total - len(jobs), desc="eval", unit="variation",
    ) as bar:
        for record in finished:
            f.write(json.dumps(record) + "\n")
            f.flush()
            os.fsync(f.fileno())
            records[(record["digest"], record["id"])] = cast(TrialRecord, record)
            bar.set_postfix(outcome=record["outcome"])
            bar.update()
    run = {
        "ran": len(jobs), "wall_seconds": time.perf_counter() - start,
        "backend": "ray" if ray else "local",
        "workers": None if ray else min(workers, max(len(jobs), 1)),
        "load_average_start": list(load), "load_average_end": list(os.getloadavg()),
    }
    return records, run


def combined_digest(digests: Sequence[str]) -> str:
    """One digest for the records of several teachers' digests (a single one: itself)."""
    if len(digests) == 1:
        return digests[0]
    return hashlib.sha256(",".join(digests).encode()).hexdigest()[:16]


def read_records(
    path: Path, digests: str | Collection[str], task: Task
) -> list[TrialRecord]:
    """The records of ``path`` (``results.jsonl``) of ``task`` under ``digests`` (one or
    several), the last one per digest and id; a line cut short by an interruption, not UTF-8,
    or not a record (:func:`_is_record`, :func:`_of_task`: an ``id`` that is no whole number
    >= 0, an ``outcome`` not of the task's, as file names are made of them; a number the
    summary reads missing), is skipped, so its variation runs again."""
    wanted = {digests} if isinstance(digests, str) else set(digests)
    records = {
        (r["digest"], r["id"]): r for r in _records(path)
        if r["digest"] in wanted and _of_task(r, task)
    }
    return list(records.values())


def _records(path: Path) -> Iterator[TrialRecord]:
    """The lines of ``path`` that are records (:func:`_is_record`), in order; none if missing."""
    if not path.exists():
        return
    yield from (cast(TrialRecord, r) for r in _json_lines(path) if _is_record(r))


def _json_lines(path: Path) -> Iterator[object]:
    """The values of the lines of ``path`` that are whole JSON, in order (a line cut short or
    not UTF-8 is passed over)."""
    check_regular(path)
    for line in path.read_bytes().splitlines():
        try:
            yield json.loads(line.decode())
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):
            continue


def _cut_short(path: Path) -> bool:
    """Whether ``path`` holds only what an evaluation interrupted in its first records leaves:
    lines that are blank, NUL bytes (a file system's unwritten tail) or a JSON object, whole
    with a ``digest`` and an ``id`` (a record of any form) or cut short; nothing at all. A file
    of other lines (someone's notes, other JSON) is someone else's."""
    check_regular(path)
    for raw in path.read_bytes().splitlines():
        line = raw.strip(b"\x00 \t\r")
        try:
            value = json.loads(line.decode()) if line else None
        except (UnicodeDecodeError, json.JSONDecodeError, RecursionError):
            if not line.startswith(b"{"):
                return False
            continue
        if value is not None and not (isinstance(value, dict) and {"digest", "id"} <= value.keys()):
            return False
    return True


def _is_record(record: object) -> bool:
    """Whether ``record`` has the form of a variation's record where file names, the summary,
    the outcome figure and the failure videos read it."""
    if not (
        isinstance(record, dict) and isinstance(record.get("digest"), str)
        and type(record.get("id")) is int and record["id"] >= 0
        and isinstance(record.get("outcome"), str) and type(record.get("teacher")) is int
        and all(is_number(record.get(k)) for k in (
            "seconds", "physics_min_distance_m", "clearance_gap_m"))
        and isinstance(record.get("plan"), dict)
        and is_number(record["plan"].get("min_distance_m"))
        and isinstance(record.get("mahalanobis"), dict)
        and is_number(record["mahalanobis"].get("rms"))
        and isinstance(record.get("replays"), list) and record["replays"]
        and all(isinstance(r, dict) and is_number(r.get("min_distance_m"))
                for r in record["replays"])
        and isinstance(record.get("settings"), dict)
        and isinstance(record["settings"].get("in_path"), bool)
    ):
        return False
    try:
        Variation.from_json(record["settings"])
    except (TypeError, ValueError, KeyError, AttributeError, ImitateError):
        return False
    return True


def _of_task(record: TrialRecord, task: Task) -> bool:
    """Whether a record (:func:`_is_record`) is of ``task``: one of its outcomes, its score's
    numbers, its critical phase's errors and changes (what ``compare`` pairs), its own
    settings."""
    plan, change = record["plan"], record.get("change")
    if not (
        record["outcome"] in task.outcomes
        and all(is_number(record.get(k)) for k in score_keys(task))
        and all(is_number(r.get(task.score.measure)) for r in record["replays"])
        and all(is_number(plan.get(k)) for k in error_keys(task))
        and isinstance(plan.get("nullspace_push"), bool)
        and isinstance(change, dict)
        and all(is_number(change.get(k)) for k in (*change_keys(task), "low_variance_m"))
    ):
        return False
    try:
        task.settings(Variation.from_json(record["settings"]).options)
    except ImitateError:
        return False
    return True


def last_records(out: Path) -> list[TrialRecord]:
    """The records of the last evaluation into ``out`` (an evaluation's folder, e.g.
    ``RUN_DIR/eval/default-w10000-variance``; the digests of its ``summary.json``), sorted by
    teacher and id.

    Raises:
        ImitateError: ``out`` holds no evaluation, or a ``summary.json`` of another form.
    """
    out = Path(out)
    check_regular(out / "summary.json")
    if not (out / "summary.json").is_file():
        raise ImitateError(
            f"{out / 'summary.json'} is missing: give the folder `imitate eval` printed "
            "(RUN_DIR/eval/<suite>-w<weight>-<similarity>, or its --out)"
        )
    summary = load_json(out / "summary.json")
    try:
        digests = [t["digest"] for t in summary.get("teachers", ())] or [summary["suite_digest"]]
        task = get_task(summary.get("task", tasks.DEFAULT))  # written before it: the default
        if not all(isinstance(d, str) for d in digests):
            raise TypeError(f"digests {digests!r:.60} are not all text")
    except (KeyError, TypeError, AttributeError) as err:
        raise ImitateError(
            f"{out / 'summary.json'} is not an evaluation's summary ({type(err).__name__}: "
            f"{err}); run the evaluation again"
        ) from err
    order = {d: i for i, d in enumerate(digests)}
    records = read_records(out / RESULTS, digests, task)
    return sorted(records, key=lambda r: (order[r["digest"]], r["id"]))


def check_counts(suite: Suite, n: int | None, workers: int | None) -> tuple[int, int]:
    """``n`` and ``workers`` with their defaults (the suite's ``variations``, every core).

    Raises:
        ImitateError: either out of its range.
    """
    n = suite["variations"] if n is None else n
    workers = (os.cpu_count() or 1) if workers is None else workers
    most = KEYS["variations"].high
    for flag, value, high in (("--n", n, most), ("--workers", workers, 1024)):
        if not 1 <= value <= high:
            raise ImitateError(f"{flag} {value} not accepted: 1..{high:g}")
    return n, workers


def _end_line(path: Path) -> None:
    """End a line cut short by an interruption, so the next record starts on its own."""
    if path.exists() and path.stat().st_size:
        with open(path, "rb+") as f:
            f.seek(-1, os.SEEK_END)
            if f.read(1) != b"\n":
                f.write(b"\n")
