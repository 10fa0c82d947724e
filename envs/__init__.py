"""The simulation, installed as ``imitate.envs``: scene assembly, physics, rendering, the teacher's
motion and the Gymnasium environment ``imitate/Pouring-v0`` (registered by ``import imitate``).

Nothing here imports the learner, the tracker or the planner: they build on this package.
"""
