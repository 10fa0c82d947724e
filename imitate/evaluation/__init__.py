"""``imitate eval``: a learned model reproduced in seeded variations of the scene and physics.

:mod:`~imitate.evaluation.suite` (the distribution), :mod:`~imitate.evaluation.variation` (one
drawn variation), :mod:`~imitate.evaluation.trial` (plan, replays, outcome),
:mod:`~imitate.evaluation.record` (a variation's record),
:mod:`~imitate.evaluation.parallel` (worker processes or Ray), :mod:`~imitate.evaluation.report`
(summary, figure, videos), :mod:`~imitate.evaluation.suite_run` (the whole evaluation, resumable),
:mod:`~imitate.evaluation.teachers` (the learned models of several teacher seeds),
:mod:`~imitate.evaluation.compare` (similarity weightings on the same variations, paired) and
:mod:`~imitate.evaluation.compare_report` (its tables and figure).

No task is named here: the run's task (:class:`~imitate.envs.task.Task`, from its
``config.json``) builds the scene and the physics, measures the replays, names the outcomes
and the score, and ships the named suites.
"""

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from imitate.evaluation.report import text
    from imitate.evaluation.suite import Suite, load_suite, named_suite, suite_names
    from imitate.evaluation.suite_run import default_out, evaluate
    from imitate.evaluation.teachers import run_task

__all__ = [
    "Suite", "default_out", "evaluate", "load_suite", "named_suite", "run_task", "suite_names",
    "text",
]

# The names and their modules, imported when first asked for (``imitate eval --help`` reads
# the suite's keys only: no MuJoCo).
_LAZY = {
    "default_out": "suite_run", "evaluate": "suite_run", "text": "report", "Suite": "suite",
    "load_suite": "suite", "named_suite": "suite", "suite_names": "suite",
    "run_task": "teachers",
}


def __getattr__(name: str):
    """The names of :data:`_LAZY`, imported when first asked for."""
    if name in _LAZY:
        import importlib

        return getattr(importlib.import_module(f"imitate.evaluation.{_LAZY[name]}"), name)
    raise AttributeError(f"module 'imitate.evaluation' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
