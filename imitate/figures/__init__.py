"""The run's figures (:mod:`~imitate.figures.plots`, matplotlib's Agg backend), drawn in a worker
process (:mod:`~imitate.figures.drawing`)."""
