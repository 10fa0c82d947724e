"""The oracle: learning from the teacher's true object poses instead of the tracked ones."""

from __future__ import annotations

import numpy as np

from imitate.envs.task import get_task
from imitate.envs.teacher_motion import TeacherConfig, TeacherMotion, script_demonstrations
from imitate.learning import LearnedModel, LearningConfig, learn
from imitate.taskspace import TaskSpace

__all__ = ["oracle_model", "true_demos"]


def true_demos(
    motion: TeacherMotion, gaze: np.ndarray, times: np.ndarray, space: TaskSpace
) -> list[np.ndarray]:
    """Ground-truth task-space demonstrations of the teacher's session.

    Args:
        motion: The teacher's session.
        gaze: ``(3, 3)`` gaze frame the task space is expressed in.
        times: ``(n,)`` session times [s] to sample; each demonstration takes those within its
            start and end.
        space: The task's space (of the tool, the target and the script's places).

    Returns:
        Per demonstration, ``(n, m)`` task-space samples.
    """
    return [
        space({"tool": (position[0], axis[0]), "target": (position[1], axis[1]),
               **{p.name: (np.broadcast_to(p.pos, position[0].shape), None)
                  for p in motion.places[i]}}, gaze)
        for i, (position, axis) in enumerate(motion.demonstration_frames(times))
    ]


def oracle_model(
    gaze: np.ndarray,
    teacher: TeacherConfig | None = None,
    learning: LearningConfig | None = None,
    rate: float = 50.0,
) -> LearnedModel:
    """Learns the task from the teacher's ground-truth poses, sampled at ``rate`` [Hz] from
    each demonstration's start (default teacher; default learning: BIC over ``K <= 20``)."""
    teacher = teacher or TeacherConfig()
    motion = script_demonstrations(teacher)
    times = np.concatenate(
        [np.arange(start, end, 1.0 / rate) for start, end in motion.boundaries]
    )
    demos = true_demos(motion, gaze, times, get_task(teacher.task).space)
    return learn(demos, rate=rate, config=learning or LearningConfig(k_max=20))
