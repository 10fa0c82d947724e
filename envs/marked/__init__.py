"""The marked pour: the robot pours from the bottle in its right hand into the glass in its left,
holding the glass over a marker standing on the table, wherever the marker stands. Its task
space is not eq. 1: the glass relative to the marker is part of it. ``task.TASK`` is the task;
``options`` its own settings."""
