"""The oracle: learning from the teacher's true object poses instead of the tracked ones."""

from __future__ import annotations

import numpy as np

from imitate.envs.teacher_motion import TeacherConfig, TeacherMotion, script_demonstrations
from imitate.learning import LearnedModel, LearningConfig, learn
from imitate.taskspace import task_space

__all__ = ["oracle_model", "true_demos"]


def true_demos(motion: TeacherMotion, gaze: np.ndarray, times: np.ndarray) -> list[np.ndarray]:
    """Ground-truth task-space demonstrations (eq. 1) of the teacher's session.

    Args:
        motion: The teacher's session.
        gaze: ``(3, 3)`` gaze frame the task space is expressed in.
        times: ``(n,)`` session times [s] to sample; each demonstration takes those within its
            start and end.

    Returns:
        Per demonstration, ``(m, 7)`` task-space samples.
    """
    return [
        task_space(position[0], axis[0], position[1], axis[1], gaze)
        for position, axis in motion.demonstration_frames(times)
    ]


def oracle_model(
    gaze: np.ndarray,
    teacher: TeacherConfig | None = None,
    learning: LearningConfig | None = None,
    rate: float = 50.0,
) -> LearnedModel:
    """Learns the task from the teacher's ground-truth poses, sampled at ``rate`` [Hz] from
    each demonstration's start (default teacher; default learning: BIC over ``K <= 20``)."""
    motion = script_demonstrations(teacher or TeacherConfig())
    times = np.concatenate(
        [np.arange(start, end, 1.0 / rate) for start, end in motion.boundaries]
    )
    demos = true_demos(motion, gaze, times)
    return learn(demos, rate=rate, config=learning or LearningConfig(k_max=20))
