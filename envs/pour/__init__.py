"""The pouring task: the robot pours from the bottle in its right hand into the glass in its
left (the paper's worked example). ``task.TASK`` is the task; ``options`` its own settings."""
