"""What each artifact was made from: ``manifest.json``, one record per stage that has run.

A record holds the settings the stage ran with (those of the whole run, of the stage and of the
stages before it), and the sha256 of every file it read and wrote, paths relative to the run
directory::

    {"learn": {"settings": {"seed": 0, "n_demos": 5, ..., "oracle": false},
               "inputs": {"observations.npz": "9f2c...", "demos.npz": "41ab..."},
               "outputs": {"model.npz": "c07e..."}}, ...}

Before a stage runs, :func:`stale` follows the records back from the files the stage reads:
each must be the file its stage wrote, made from the files now present, with the settings now
in force. A copied-in or edited artifact, one left from before an earlier stage was re-run, or
one made under another seed is named, with the stage to re-run.
"""

from __future__ import annotations

import functools
import hashlib
import json
from collections.abc import Callable, Mapping
from pathlib import Path

from imitate.envs import tasks
from imitate.errors import ImitateError, quoted, shell_word
from imitate.rundir import layout
from imitate.rundir.artifacts import digest, load_json
from imitate.stages import table
from imitate.stages.config import RunConfig, settings

__all__ = ["MANIFEST", "code_digest", "digest", "load", "outdated", "recorded", "stale"]

MANIFEST = layout.MANIFEST


def load(run_dir: Path) -> dict[str, dict]:
    """The records of ``run_dir`` by stage name (none when it has no manifest yet).

    Raises:
        ImitateError: ``manifest.json`` is unreadable or not a manifest.
    """
    path = Path(run_dir) / MANIFEST
    if not path.exists():
        return {}
    manifest = load_json(path, hint=table.rerun(path))
    fields = ("settings", "inputs", "outputs")
    if not (
        isinstance(manifest, dict)
        and all(isinstance(r, dict) and all(isinstance(r.get(f), dict) for f in fields)
                for r in manifest.values())
    ):
        raise ImitateError(
            f"{path} is not a manifest (an object of stage records with {fields}); delete it "
            f"and re-run `imitate run --out {run_dir}`"
        )
    return manifest


def recorded(
    manifest: dict[str, dict],
    run_dir: Path,
    stage: table.Stage,
    config: RunConfig,
    outputs: dict[str, Path],
) -> dict[str, dict]:
    """``manifest`` with the record of ``stage`` run with ``config`` in ``run_dir`` (the other
    records kept), in run order; ``outputs`` maps each file the stage wrote (relative path) to
    where its bytes are now (a staged temporary file)."""
    run_dir = Path(run_dir)
    new = {
        "settings": _settings(stage, config),
        "inputs": {f: digest(run_dir / f) for f in stage.reads if (run_dir / f).is_file()},
        "outputs": {name: digest(path) for name, path in outputs.items()},
    }
    records = {**manifest, stage.name: new}
    return {name: records[name] for name in table.NAMES if name in records}


def stale(
    run_dir: Path, stage: table.Stage, config: RunConfig, manifest: dict[str, dict]
) -> list[str]:
    """Why the inputs of ``stage`` in ``run_dir`` do not follow from ``config`` and each other:
    one line per upstream stage at fault, earliest first, each naming the stage to re-run.
    Files that are absent are left to the stage (it names them)."""
    run_dir = Path(run_dir)
    upstream = _upstream(stage)
    needed = {f for s in (stage, *upstream) for f in s.reads}
    current = _current(run_dir)
    problems = []
    for s in upstream:
        files = [f for f in s.writes if f in needed and (run_dir / f).is_file()]
        if not files:
            continue
        problem = _fault(s, files, manifest.get(s.name), _settings(s, config), current)
        if problem:
            problems.append(f"{problem}; re-run `imitate {s.name} {shell_word(run_dir)}`")
    return problems


def code_digest() -> str:
    """sha256 (hex) of the code that makes results: every file of the packages ``imitate``,
    ``imitate.envs`` and ``imitate.models`` (sources, MJCF) but compiled caches, by path
    relative to its package. The same for an editable install and a wheel of the same files."""
    import imitate.envs  # binds imitate too
    import imitate.models

    packages = (imitate, imitate.envs, imitate.models)
    assert all(p.__file__ is not None for p in packages)  # regular packages, not namespace ones
    roots = [Path(str(p.__file__)).parent for p in packages]
    h = hashlib.sha256()
    for package, root in zip(packages, roots, strict=True):
        # A wheel puts envs/ and models/ inside imitate/ (the clone keeps them beside it): each
        # file counts once, under its own package, so both installs give one digest.
        nested = [r for r in roots if r != root and r.is_relative_to(root)]
        for path in sorted(root.rglob("*")):
            if any(path.is_relative_to(r) for r in nested):
                continue
            if path.is_file() and "__pycache__" not in path.parts:
                h.update(f"{package.__name__}/{path.relative_to(root).as_posix()}".encode())
                h.update(hashlib.sha256(path.read_bytes()).digest())
    return h.hexdigest()


def outdated(
    run_dir: Path, config: RunConfig, manifest: dict[str, dict],
    staged: Mapping[str, Path] | None = None,
) -> dict[str, str]:
    """The stages whose files in ``run_dir`` no longer follow from the run: not the files the
    manifest records (a commit cut short between its renames, or changed since), made from an
    input that changed since, or with other settings than ``config``'s. By stage name, why
    (``"made from another plan.npz"``). ``staged``: files written but not yet in place
    (relative path -> where they are now)."""
    current = _current(Path(run_dir), staged)
    found = {}
    for s in table.STAGES:
        rec = manifest.get(s.name)
        present = [f for f in s.writes if f != layout.CONFIG and current(f)]
        if rec is None:
            if present:
                found[s.name] = f"{present[0]} is not recorded in {MANIFEST}"
            continue
        if not any(current(f) for f in rec["outputs"]):
            continue
        differ = [f for f in rec["outputs"] if current(f) not in (None, rec["outputs"][f])]
        why = (
            f"{differ[0]} is not the file it wrote (a commit cut short, or changed since)"
            if differ else _drift(s, rec, _settings(s, config), current)
        )
        if why:
            found[s.name] = why
    return found


def _current(
    run_dir: Path, staged: Mapping[str, Path] | None = None
) -> Callable[[str], str | None]:
    """``current(name)``: the digest of the run's file ``name`` now (``staged``: files written
    but not yet in place, relative path -> where they are), ``None`` if absent or no name a run
    holds (:data:`~imitate.rundir.layout.OWN`: a manifest's names are not followed out of the
    run); each hashed once."""
    staged = staged or {}

    @functools.cache
    def current(name: str) -> str | None:
        if name not in staged and name not in layout.OWN:
            return None
        path = staged.get(name, run_dir / name)
        return digest(path) if path.is_file() else None

    return current


def _drift(stage: table.Stage, rec: dict, now: dict, current) -> str:
    """How what ``stage`` wrote (its record ``rec``) no longer follows from the files and the
    settings ``now`` in force: ``"made from another plan.npz, changed since"``, ``"made with
    seed=0, not 5"``; ``""`` if it does."""
    for f, sha in rec["inputs"].items():
        if f in stage.reads and current(f) not in (None, sha):
            return f"made from another {f}, changed since"
    for name, value in rec["settings"].items():
        if name in now and now[name] != value:
            return f"made with {name}={quoted(value)}, not {quoted(now[name])}"
    return ""


def _fault(stage: table.Stage, files: list[str], rec: dict | None, now: dict, current) -> str:
    """What is wrong with ``files`` that ``stage`` wrote, given its record ``rec``, the settings
    ``now`` in force and ``current(name)`` (a file's digest, ``None`` if absent); ``""`` if
    nothing."""
    named = " and ".join(files)
    were = "was" if len(files) == 1 else "were"
    if rec is None:
        return f"{named} {were} not recorded in {MANIFEST} as written by `imitate {stage.name}`"
    for f in files:
        if current(f) != rec["outputs"].get(f):
            return (
                f"{f} is not the file `imitate {stage.name}` wrote (changed since, or copied "
                f"from another run)"
            )
    why = _drift(stage, rec, now, current)
    return f"{named} {were} {why}" if why else ""


def _settings(stage: table.Stage, config: RunConfig) -> dict:
    """The settings ``stage``'s outputs depend on, as JSON values: the whole run's, its own and
    the earlier stages', the task's own settings among them by the stage that first uses each."""
    names = table.NAMES[: table.NAMES.index(stage.name) + 1]
    values = json.loads(json.dumps(config.to_json()))
    chosen = {name: values[name] for name, _, _ in settings([None, *names])}
    declared = tasks.options(config.task)
    chosen["options"] = {
        name: value for name, value in values["options"].items() if declared[name].stage in names
    }
    return chosen


def _upstream(stage: table.Stage) -> list[table.Stage]:
    """The stages whose outputs ``stage`` reads, directly or through another, in run order."""
    needed = set(stage.reads)
    for s in reversed(table.STAGES):
        if needed & set(s.writes):
            needed |= set(s.reads)
    return [s for s in table.STAGES if needed & set(s.writes) and s is not stage]
