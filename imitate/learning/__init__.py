"""Learning (paper section IV and V-A): demonstrations to a GMR mean and variance over time.

:func:`learn` aligns task-space demonstrations by DTW (:mod:`~imitate.learning.dtw`), chooses the
number of GMM components by BIC (:mod:`~imitate.learning.bic`, from the K-means sweep of
:mod:`~imitate.learning.kmeans`), trains the GMM by EM (:mod:`~imitate.learning.gmm`) and
conditions it on time (:mod:`~imitate.learning.gmr`); :class:`LearnedModel` holds the result.
"""

from imitate.learning.model import LearnedModel, LearningConfig, learn, time_stacked

__all__ = ["LearnedModel", "LearningConfig", "learn", "time_stacked"]
