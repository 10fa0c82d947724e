"""Demonstrations in the task space: cut from the tracks at stillness
(:mod:`~imitate.demos.segment`), from the teacher's script (:mod:`~imitate.demos.oracle`, the
ground truth instead of perception) or drawn (:mod:`~imitate.demos.synthetic`)."""
