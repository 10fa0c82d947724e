"""The insertion task: the robot puts the stick in its right hand into the glass held in its
left. ``task.TASK`` is the task; ``options`` its own settings."""
