"""The keys of ``report.json``, declared: the unit and meaning of each (``python -m
imitate.rundir.schema`` prints them as a table; ``tests/test_api.py`` checks that a run's report
has exactly these keys).

Every stage merges its sections into the report; ``schema`` is the version of this layout,
raised when a key changes meaning or goes away. Keys are dotted; ``a[].b`` is key ``b`` of every
item of the list ``a``; ``<stage>`` and ``<name>`` stand for any stage and any artifact. A run's
task adds keys of its own (:func:`report_keys`): its critical phase's in the optimization
section, its measures' in the replay section.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from imitate.errors import ImitateError
from imitate.rundir.artifacts import load_json

__all__ = [
    "KINDS", "PHASE_KEYS", "REPORT_KEYS", "REPORT_SCHEMA", "check_schema", "check_values",
    "load_report", "markdown", "report_keys",
]

REPORT_SCHEMA = 1  # report["schema"]

# key: (unit, meaning; "{outcomes}" stands for the task's)
REPORT_KEYS: dict[str, tuple[str, str]] = {
    "schema": ("-", "version of this layout: 1"),
    "seed": ("-", "seed of the run"),
    "demos.detected": ("-", "demonstrations the segmentation found"),
    "demos.expected": ("-", "demonstrations the teacher showed"),
    "demos.boundary_err_s_max": (
        "s",
        "largest start or end error of a found demonstration against the true one",
    ),
    "perception.pos_err_mm_median": (
        "mm",
        "median tracked-point position error against ground truth",
    ),
    "perception.pos_err_mm_p95": ("mm", "its 95th percentile"),
    "perception.angle_err_deg_median": (
        "deg",
        "median error of the objects' angles around the gaze",
    ),
    "perception.detected_fraction": ("1", "fraction of (object, frame) pairs the tracker found"),
    "perception.long_gaps": ("-", "tracking gaps too long to interpolate"),
    "perception.render_pairs_per_s": ("1/s", "stereo pairs rendered per second"),
    "perception.track_pairs_per_s": ("1/s", "stereo pairs tracked and triangulated per second"),
    "learning.source": ("-", "`perception` or `ground truth (oracle)`"),
    "learning.bic": (
        "-",
        "how the number of components was chosen: `full` (EM for every K) or `fast`",
    ),
    "learning.n_components": ("-", "GMM components K used"),
    "learning.n_components_fast_bic": ("-", "K the fast BIC chooses"),
    "learning.n_components_full_bic": ("-", "K the full BIC chooses"),
    "learning.seconds": ("s", "time to learn (DTW, BIC, EM, GMR)"),
    "learning.bridged_samples": (
        "-",
        "tracked samples missing in the demonstrations, bridged linearly",
    ),
    "learning.task_space": (
        "-", "the task space learned in, its terms (`--task-space`; TP-GMM's frames for `tpgmm`)"
    ),
    "learning.space_ratios": (
        "-",
        "with `--task-space auto`, each candidate relation and its invariance ratio where the "
        "task is decided, `[relation, ratio]` (`imitate.demos.space_selection`); empty otherwise",
    ),
    "optimization.collision_weight": ("-", "weight of the collision cost of the plan"),
    "optimization.similarity": (
        "-",
        "the similarity weighting of the plan (`variance`: eq. 21, `uniform`, `inverted`, "
        "`precision`)",
    ),
    "optimization.sigma_max_scale": (
        "-",
        "eq. 21's `sigma_max` as a multiple of each dimension's largest GMR variance (1: the "
        "paper's)",
    ),
    "optimization.seconds": ("s", "time to optimize the plan"),
    "optimization.iterations": ("-", "optimizer iterations"),
    "optimization.converged": ("-", "whether the stopping rule was met within `max_iter`"),
    "optimization.min_distance_m": (
        "m",
        "smallest signed distance between geoms that must not touch, over the plan",
    ),
    "optimization.closest_pair": (
        "-",
        "the two geoms at that distance (empty if none is within 0.2 m)",
    ),
    "optimization.message": ("-", "what happened, in words"),
    "optimization.sweep[].weight": ("-", "collision weight of one plan of the Fig. 9 sweep"),
    "optimization.sweep[].min_distance_m": ("m", "its smallest signed distance"),
    "optimization.sweep[].max_deviation_m": (
        "m",
        "largest distance of its relative position (dx, dy, dz) from the weight-0 plan's",
    ),
    "optimization.sweep[].deviation_m2": (
        "m^2",
        "its squared deviation from the GMR mean, summed over steps",
    ),
    "optimization.sweep[].deviation_high_variance_share": (
        "1",
        "share of that in steps of above-median GMR variance",
    ),
    "optimization.sweep[].change_from_first_m2": (
        "m^2",
        "squared change from the sweep's first plan, summed over steps",
    ),
    "optimization.sweep[].change_high_variance_share": (
        "1",
        "share of that in steps of above-median GMR variance",
    ),
    "replay.min_distance_m": (
        "m",
        "smallest signed distance between geoms that must not touch, in physics",
    ),
    "replay.task_err_m_max": (
        "m",
        "largest relative-position error of the objects against the plan, in physics",
    ),
    "replay.outcome": ("-", "the outcome of the plan and its replays: {outcomes}"),
    "replay.success": ("-", "the outcome is success"),
    "video.frames": ("-", "frames of `video.mp4`"),
    "video.seconds": ("s", "its length"),
    "timings.<stage>": ("s", "wall time of each stage run last"),
    "artifacts.<name>": (
        "-",
        "path of each artifact present, relative to the run directory, by file stem",
    ),
}

# The keys of a task's critical phase, after "optimization.closest_pair" (``{phase}``: its name).
PHASE_KEYS = {
    "optimization.{phase}_phase_err_m": (
        "m",
        "largest relative-position error from the GMR mean in the task's critical phase",
    ),
    "optimization.{phase}_phase_err_deg": (
        "deg",
        "largest tool or target angle error from the GMR mean in it",
    ),
}


def report_keys(
    phase: str, outcomes: Sequence[str], task_keys: Mapping[str, tuple[str, str]]
) -> dict[str, tuple[str, str]]:
    """The keys of the report of a run whose task has the critical phase ``phase`` (its name),
    the ``outcomes`` and the keys ``task_keys`` of its own (``replay.*``: unit and meaning):
    :data:`REPORT_KEYS` with :data:`PHASE_KEYS` and ``task_keys`` in place."""
    keys: dict[str, tuple[str, str]] = {}
    for key, (unit, meaning) in REPORT_KEYS.items():
        if key == "replay.min_distance_m":
            keys.update(task_keys)
        keys[key] = (unit, meaning.format(outcomes=_alternatives(outcomes)))
        if key == "optimization.closest_pair":
            keys.update({k.format(phase=phase): v for k, v in PHASE_KEYS.items()})
    return keys


def _alternatives(words: Sequence[str]) -> str:
    """``a, b or c``."""
    return " or ".join(filter(None, (", ".join(words[:-1]), *words[-1:])))


def check_schema(report: Any, path: Path) -> dict:
    """``report`` (read from ``path``) if it is a report of this layout.

    Raises:
        ImitateError: it is not an object, or of another ``schema``.
    """
    if not isinstance(report, dict):
        raise ImitateError(f"{path} is not a report (an object); delete it to start a new one")
    schema = report.get("schema", REPORT_SCHEMA)
    if schema != REPORT_SCHEMA:
        raise ImitateError(
            f"{path} has schema {schema!r}; this imitate reads and writes schema "
            f"{REPORT_SCHEMA}: run the run again with it, or delete {path.name} to start a new one"
        )
    return report


def load_report(path: Path) -> dict:
    """The report in ``path`` (``report.json``), read and checked by :func:`check_schema`.

    Raises:
        ImitateError: it is missing, unreadable or not a report of this layout; the message
            says to delete it to start a new report.
    """
    return check_schema(load_json(path, hint="delete it to start a new report"), path)


# The kind of each key whose unit is "-" (the others are numbers, or null where not measured).
KINDS: dict[str, type | tuple[type, ...]] = {
    "seed": int, "demos.detected": int, "demos.expected": int, "perception.long_gaps": int,
    "learning.source": str, "learning.bic": str, "learning.n_components": int,
    "learning.n_components_fast_bic": int, "learning.n_components_full_bic": int,
    "learning.bridged_samples": int, "learning.task_space": str, "learning.space_ratios": list,
    "optimization.collision_weight": (int, float),
    "optimization.similarity": str, "optimization.sigma_max_scale": (int, float),
    "optimization.iterations": int, "optimization.converged": bool,
    "optimization.closest_pair": list, "optimization.message": str,
    "optimization.sweep[].weight": (int, float), "replay.outcome": str, "replay.success": bool,
    "video.frames": int, "artifacts.<name>": str,
}


_MISSING = object()  # a declared key not in its section


def check_values(
    report: dict,
    path: Path,
    keys: Mapping[str, tuple[str, str]] = REPORT_KEYS,
    kinds: Mapping[str, type | tuple[type, ...]] = KINDS,
) -> None:
    """Raise ``ImitateError`` naming ``path``, the key and its value if a section of ``report``
    (read from ``path``) lacks a key ``keys`` declares for it (:func:`report_keys` of the run's
    task; a stage writes its sections whole, and the page and the summary read them so) or
    holds one of another kind (a number where the unit is one, ``kinds`` where it is ``-``: the
    task's with :data:`KINDS`); keys it does not declare are left alone."""
    for key in keys:
        kind = kinds.get(key, (int, float, type(None)))
        section, _, rest = key.partition(".")
        if key == "schema" or not rest:
            if key in report and not _of_kind(report[key], kind):
                raise _wrong(path, key, report[key], kind)
            continue
        for name, value in _values(report.get(section), rest, section):
            if value is _MISSING:
                raise ImitateError(
                    f"{path}: {name} is missing; delete it to start a new report"
                )
            if not _of_kind(value, kind):
                raise _wrong(path, name, value, kind)


def _values(node: Any, key: str, at: str) -> list[tuple[str, Any]]:
    """``(dotted name, value)`` of ``key`` (``a.b``, ``a[].b``, ``<name>``) under ``node``
    (none if ``node`` is no object; :data:`_MISSING` where a name is not in an object)."""
    head, _, rest = key.partition(".")
    if not isinstance(node, dict):
        return []
    if head.startswith("<"):
        children = list(node.items())
    elif head.endswith("[]"):
        items = node.get(head[:-2])
        if not isinstance(items, list):
            return []
        return [
            found for i, item in enumerate(items)
            for found in _values(item, rest, f"{at}.{head[:-2]}[{i}]")
        ]
    elif head not in node:
        return [(f"{at}.{head}", _MISSING)]
    else:
        children = [(head, node[head])]
    if not rest:
        return [(f"{at}.{name}", value) for name, value in children]
    return [found for name, value in children for found in _values(value, rest, f"{at}.{name}")]


def _of_kind(value: Any, kind: type | tuple[type, ...]) -> bool:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    return isinstance(value, kinds) and (bool in kinds or not isinstance(value, bool))


def _wrong(path: Path, name: str, value: Any, kind: type | tuple[type, ...]) -> ImitateError:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    words = {int: "a whole number", float: "a number", str: "text", bool: "true or false",
             list: "a list", type(None): "null"}
    accepted = " or ".join(dict.fromkeys(words[k] for k in kinds if k is not int or float
                                         not in kinds))
    shown = repr(value) if len(repr(value)) <= 80 else repr(value)[:77] + "..."
    return ImitateError(
        f"{path}: {name}={shown} not accepted: {accepted}; delete it to start a new report"
    )


def markdown(keys: Mapping[str, tuple[str, str]] = REPORT_KEYS) -> str:
    """``keys`` as a Markdown table (key, unit, meaning)."""
    rows = [f"| `{key}` | {unit} | {meaning} |" for key, (unit, meaning) in keys.items()]
    return "\n".join(["| key | unit | meaning |", "|---|---|---|", *rows])


if __name__ == "__main__":
    print(markdown(report_keys("<phase>", ("the task's outcomes",), {
        "replay.<key>": ("-", "the task's own keys (its `keys`)"),
    })))
