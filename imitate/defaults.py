"""The defaults and choices the command line shows, as plain constants: importing this module
loads neither MuJoCo, numba, SciPy nor matplotlib, so that ``imitate CMD --help`` is quick.

The modules that use them take them from here (the table's extent from
:mod:`imitate.models.scene`, as light).
"""

from imitate.models.scene import TABLE_X, TABLE_Y

__all__ = [
    "BIC_METHODS", "COLLISION_WEIGHT", "DEFAULT_BIC", "EXPORT_FORMATS",
    "MAX_ITER", "MAX_WEIGHT", "NULLSPACE_PUSH", "OBSTACLE_MAX_LIFT", "OBSTACLE_SHAPES",
    "PATH_LENGTH_WEIGHT", "RUN_SIMILARITIES", "SIGMA_MAX_SCALE", "SIMILARITIES",
    "SIMILARITY", "SMOOTHING", "TABLE_X", "TABLE_Y", "TEACHER_VARIATION", "TEACHER_VARIATIONS",
]

# the teacher (imitate.envs.teacher_motion: TEACHER_VARIATIONS, TeacherConfig.variation)
TEACHER_VARIATIONS = ("aligned", "misaligned", "misleading", "coupled")
TEACHER_VARIATION = "aligned"
# learning (imitate.demos.segment: StillnessConfig.smoothing [s]; imitate.learning.bic)
SMOOTHING = 0.3
BIC_METHODS = ("full", "fast")
DEFAULT_BIC = "full"
# the planner (imitate.motion: SIMILARITIES, PlanConfig)
SIMILARITIES = (
    "variance", "uniform", "inverted", "precision", "inverse_variance", "oracle", "importance",
)
# those a run can plan with: ``importance`` reads a teacher's measured tolerance, which
# ``imitate compare`` and ``imitate eval`` load
RUN_SIMILARITIES = tuple(s for s in SIMILARITIES if s != "importance")
SIMILARITY = "variance"
COLLISION_WEIGHT = 10000.0
# Largest collision weight, 100 times the default: it keeps the weighted costs and the
# optimizer's arithmetic far from overflow (runs, suites and sweeps alike).
MAX_WEIGHT = 1e6
SIGMA_MAX_SCALE = 1.0
NULLSPACE_PUSH = True
MAX_ITER = 100
PATH_LENGTH_WEIGHT = 0.01
# the scene (imitate.envs.assembly; a task's objects and grasps: imitate.models.shapes)
OBSTACLE_SHAPES = ("box", "cylinder")
OBSTACLE_MAX_LIFT = 0.5
# imitate.export.FORMATS
EXPORT_FORMATS = ("minari", "hdf5", "lerobot")
