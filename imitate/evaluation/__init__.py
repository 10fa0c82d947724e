"""``imitate eval``: a learned model reproduced in seeded variations of the scene and physics.

:mod:`~imitate.evaluation.suite` (the distribution), :mod:`~imitate.evaluation.variation` (one
drawn variation), :mod:`~imitate.evaluation.trial` (plan, replays, outcome),
:mod:`~imitate.evaluation.parallel` (worker processes or Ray), :mod:`~imitate.evaluation.report`
(summary, figure, videos), :mod:`~imitate.evaluation.evaluate` (the whole evaluation, resumable),
:mod:`~imitate.evaluation.teachers` (the learned models of several teacher seeds),
:mod:`~imitate.evaluation.compare` (similarity weightings on the same variations, paired).
"""

from imitate.evaluation.evaluate import default_out, evaluate
from imitate.evaluation.report import text
from imitate.evaluation.suite import SUITE_NAMES, Suite, load_suite, named_suite

__all__ = ["SUITE_NAMES", "Suite", "default_out", "evaluate", "load_suite", "named_suite", "text"]
