"""Runs a stage (see :mod:`imitate.stages.table`) in a run directory, all or nothing.

Each stage reads the previous stages' artifacts in the run directory and writes its own
(atomically, see :mod:`imitate.rundir.artifacts`); :func:`run_stage` merges its numbers into
``report.json``. Every stage is a deterministic function of ``config.json`` and its inputs: the
same seed gives the same arrays and the same report (timings aside).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from imitate.envs.task import Task, get_task
from imitate.errors import ImitateError, shell_word
from imitate.rundir import layout, page
from imitate.rundir.artifacts import refuse_link, save_json, staged
from imitate.rundir.schema import KINDS, REPORT_SCHEMA, check_values, load_report, report_keys
from imitate.stages import provenance, table
from imitate.stages.config import RunConfig, load_config
from imitate.stages.files import ModelFile

__all__ = ["run_keys", "run_stage", "run_stages"]

log = logging.getLogger(__name__)


def run_stage(stage: str, run_dir: Path, config: RunConfig, force: bool = False) -> dict:
    """Run one stage in ``run_dir`` with ``config``, all or nothing: its artifacts,
    ``config.json``, its record in ``manifest.json`` (see :mod:`imitate.stages.provenance`),
    ``report.json`` (its numbers, its time and the artifacts present merged in; the sections of
    later stages dropped, as they no longer follow from it) and ``report.html`` (the same as a
    page, see :mod:`imitate.rundir.page`) are renamed into place only when the stage has
    succeeded, every destination checked first, the manifest last (its digests decide whether
    the files are the stage's, should the commit be cut short). Returns the report.

    Raises:
        ImitateError: before the stage runs, ``report.json`` or ``manifest.json`` is unusable,
            or an input is stale or from another run (with ``force``: a warning on stderr
            instead); or the stage's own errors. The directory is then unchanged.
    """
    current = table.find(stage)
    run_dir = Path(run_dir)
    task = get_task(config.task)
    manifest = provenance.load(run_dir)
    problems = provenance.stale(run_dir, current, config, manifest)
    if problems and not force:  # before the report, which a switched task would misread
        raise ImitateError(f"{problems[0]}, or add --force to go on anyway")
    previous = _previous_report(run_dir, _report_task(run_dir, task), current)
    for problem in problems:
        log.warning("%s; going on anyway (--force)", problem)
    for name in (*current.writes, layout.REPORT, layout.PAGE, layout.MANIFEST):
        refuse_link(run_dir / name)  # now, not after the stage's work, at its commit
    with staged(run_dir, last=provenance.MANIFEST) as staging:
        start = time.perf_counter()
        sections = current.body()(run_dir, config, _learned_task(run_dir, current, task))
        seconds = time.perf_counter() - start
        outputs = staging.files()
        manifest = provenance.recorded(manifest, run_dir, current, config, outputs)
        report = _report(current, sections, seconds, previous, config.seed)
        report["artifacts"] = _artifacts(run_dir, set(outputs))
        save_json(run_dir / layout.CONFIG, config.to_json())
        save_json(run_dir / layout.MANIFEST, manifest)
        save_json(run_dir / layout.REPORT, report)
        later = {
            name: (table.find(name).files, why)
            for name, why in provenance.outdated(run_dir, config, manifest, outputs).items()
        }
        for name, (files, why) in later.items():
            log.info("out of date: %s (%s); `imitate %s %s` makes it again",
                        files, why, name, shell_word(run_dir))
        page.save_run_page(run_dir, report, config.to_json(), task.words, task.objects[0],
                           task.phase, later)
    log.debug("%s wrote %s in %.1f s", stage, ", ".join(sorted(outputs)), seconds)
    return report


def run_stages(
    stages: Sequence[str], run_dir: Path, config: RunConfig, force: bool = False,
    starting: Callable[[str], None] | None = None,
) -> dict:
    """Run ``stages`` in order with :func:`run_stage`, calling ``starting(stage)`` before each;
    returns the last one's report. When the figures follow learn, their worker process
    (:func:`imitate.figures.drawing.ahead`) starts with learn, so that its imports are done by
    then (not with observe, which keeps every core busy).

    Raises:
        ImitateError: as :func:`run_stage`; the stages before the failed one are kept.
    """
    report: dict = {}
    with ExitStack() as ahead:
        for stage in stages:
            if starting is not None:
                starting(stage)
            if stage == "learn" and "figures" in stages:
                from imitate.figures import drawing  # matplotlib: only where figures follow

                ahead.enter_context(drawing.ahead())
            report = run_stage(stage, run_dir, config, force=force)
    return report


def _report(
    current: table.Stage, sections: dict, seconds: float, previous: dict, seed: int
) -> dict:
    """The report after ``current`` returned ``sections`` in ``seconds`` [s]: those of the
    earlier stages kept from ``previous``, those of later ones dropped."""
    earlier = table.STAGES[: table.STAGES.index(current)]
    kept = {name for s in earlier for name in s.sections}
    report: dict[str, Any] = {"schema": REPORT_SCHEMA, "seed": seed}
    for name in [name for s in table.STAGES for name in s.sections]:
        if name in sections:
            report[name] = sections[name]
        elif name in kept and name in previous:
            report[name] = previous[name]
    done = {s.name for s in earlier}
    timings = {s: t for s, t in previous.get("timings", {}).items() if s in done}
    report["timings"] = {**timings, current.name: seconds}
    return report


def run_keys(task: Task) -> tuple[dict[str, tuple[str, str]], dict[str, Any]]:
    """The keys of the report of a run of ``task`` (unit and meaning,
    :func:`~imitate.rundir.schema.report_keys`) and the kinds of those whose value is no number
    (:data:`~imitate.rundir.schema.KINDS` and the task's)."""
    return report_keys(task.phase, task.outcomes, task.keys), {**KINDS, **task.kinds}


def _learned_task(run_dir: Path, current: table.Stage, task: Task) -> Task:
    """``task`` as ``current`` plans and measures it: after ``learn``, in the space its model was
    learned in (``model.npz``, :meth:`Learned.task`)."""
    if layout.MODEL not in current.reads:
        return task
    return ModelFile.load_learned(run_dir).task(task)


def _report_task(run_dir: Path, task: Task) -> Task:
    """The task of the run whose report ``run_dir`` holds (another than ``task`` where this run
    starts anew over a run of another task): its ``config.json``'s, else ``task``."""
    try:
        return get_task(load_config(run_dir).task)
    except ImitateError:  # no run there yet, or one this imitate cannot read
        return task


def _previous_report(run_dir: Path, task: Task, current: table.Stage) -> dict:
    """``report.json`` of ``run_dir`` (empty if none yet), its sections that ``current`` keeps
    (the earlier stages') checked as the page will read them (with the keys of a run of
    ``task``); those ``current`` and the later stages write anew are not read (a report an
    older imitate wrote is remade from the stage that wrote it).

    Raises:
        ImitateError: it is unreadable, not an object of sections, holds a value of another
            kind than the key's (:func:`~imitate.rundir.schema.check_values`), or lacks one
            the page shows.
    """
    path = run_dir / layout.REPORT
    if not path.exists():
        return {}
    report = load_report(path)
    names = ("timings", "artifacts", *(name for s in table.STAGES for name in s.sections))
    if any(
        not isinstance(report.get(name, {}), dict) for name in names
    ):
        raise ImitateError(
            f"{path} is not a report (an object of sections); delete it to start a new report"
        )
    keys, kinds = run_keys(task)
    rewritten = {name for s in table.STAGES[table.STAGES.index(current):] for name in s.sections}
    check_values(report, path, {k: v for k, v in keys.items()
                                if k.partition(".")[0] not in rewritten}, kinds)
    return report


def _artifacts(run_dir: Path, written: set[str]) -> dict[str, str]:
    """Relative paths of the artifacts present or ``written`` now, by name (the report:
    always)."""
    report = layout.REPORT
    names = (*(name for s in table.STAGES for name in s.writes), report)
    return {
        Path(name).stem: name
        for name in names
        if name in written or (run_dir / name).exists() or name == report
    }
