"""The settings of the attractor optimization (:func:`imitate.motion.plan_from_model`)."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

from imitate import defaults
from imitate.errors import ImitateError
from imitate.motion.control import ControlConfig
from imitate.motion.costs import SIMILARITIES

__all__ = ["OPTIMIZERS", "PlanConfig"]

OPTIMIZERS = ("rprop", "lbfgs")
# The cost terms' weights, each >= 0.
WEIGHTS = ("similarity_weight", "collision_weight", "joint_limit_weight", "path_length_weight",
           "joint_acceleration_weight")


@dataclass(frozen=True)
class PlanConfig:
    """Parameters of :func:`plan_from_model`.

    Attributes:
        dt: Planning step [s].
        attractor_spacing: Time between attractors [s]: evenly spaced over the movement, each
            switched in softly (a Gaussian share, 0.4 spacings its standard deviation); ``None``
            for the paper's one attractor per GMM component (at its time mean, width and prior).
        omega_per_interval: Attractor stiffness: ``omega = omega_per_interval / L`` [rad/s]
            with ``L`` the mean interval between attractor switches.
        w_max: Eq. 21 weights at zero variance per task dimension ``(m,)``; ``None`` for
            ``1 / tolerance^2`` with 1 cm, 1 cm, 1 cm, 2 deg, 0.05, 2 deg, 0.05.
        sigma_max: Eq. 21 variance where the weight reaches 0 per dimension ``(m,)``; ``None``
            for ``sigma_max_scale`` times each dimension's largest GMR variance.
        sigma_max_scale: 1 is the paper's choice, where a dimension's weight is 0 at its
            peak-variance step, so that the plan may move freely there (Fig. 9's excursion at
            the start, where ``dy`` varies most); above 1 every step keeps a weight.
        similarity: How ``W_t`` is made (:data:`~imitate.motion.costs.SIMILARITIES`):
            ``"variance"`` (eq. 21) or an alternative with its total weight
            (:func:`~imitate.motion.costs.weighting`).
        similarity_weight, collision_weight, joint_limit_weight, path_length_weight,
            joint_acceleration_weight: ``w_i``.
        max_joint_acceleration: Joint acceleration [rad/s^2] above which the acceleration
            term costs: the position servos follow the plan's speed (the replay leads them by
            it) but not sudden changes of it.
        margin: Clearance [m] the collision cost treats as contact.
        epsilon: Width [m] of the proximity zone above ``margin``.
        optimizer: ``"rprop"`` or ``"lbfgs"``.
        max_iter: Iteration limit of each run of the optimizer (the null-space push adds two).
        tol: Converged when the best cost improved by less than ``tol`` (relative) over the
            last ``patience`` iterations.
        patience: See ``tol``.
        rprop_step: Initial iRprop- step as a fraction of each dimension's tolerance.
        nullspace_push: Whether a plan that keeps less than ``margin`` with the attractors
            alone is optimized once more with a null-space push per attractor (``Plan.push``).
        control: RMR parameters.
    """

    dt: float = 0.08
    attractor_spacing: float | None = 0.15
    omega_per_interval: float = 2.0
    w_max: tuple[float, ...] | None = None
    sigma_max: tuple[float, ...] | None = None
    sigma_max_scale: float = defaults.SIGMA_MAX_SCALE
    similarity: str = defaults.SIMILARITY
    similarity_weight: float = 1.0
    collision_weight: float = defaults.COLLISION_WEIGHT
    joint_limit_weight: float = 1.0
    path_length_weight: float = defaults.PATH_LENGTH_WEIGHT
    joint_acceleration_weight: float = 3.0
    max_joint_acceleration: float = 20.0
    margin: float = 0.011
    epsilon: float = 0.004
    optimizer: str = "rprop"
    max_iter: int = defaults.MAX_ITER
    tol: float = 1e-2
    patience: int = 5
    rprop_step: float = 0.1
    nullspace_push: bool = defaults.NULLSPACE_PUSH
    control: ControlConfig = field(default_factory=ControlConfig)

    def __post_init__(self):
        if self.optimizer not in OPTIMIZERS:
            raise ImitateError(f"optimizer {self.optimizer!r} unknown; accepted: {OPTIMIZERS}")
        if self.similarity not in SIMILARITIES:
            raise ImitateError(
                f"similarity {self.similarity!r} unknown; accepted: {SIMILARITIES}"
            )
        for name in ("dt", "omega_per_interval"):
            if not getattr(self, name) > 0:
                raise ImitateError(f"{name}={getattr(self, name)!r} not accepted: a number > 0")
        for name in WEIGHTS:
            if not getattr(self, name) >= 0:
                raise ImitateError(f"{name}={getattr(self, name)!r} not accepted: a weight >= 0")
        if self.attractor_spacing is not None and not self.attractor_spacing > 0:
            raise ImitateError(
                f"attractor_spacing={self.attractor_spacing!r} not accepted: a time > 0 [s], "
                "or None for one attractor per GMM component"
            )
        if not self.sigma_max_scale > 0:
            raise ImitateError(f"sigma_max_scale {self.sigma_max_scale} not accepted: > 0")
        if not self.max_joint_acceleration > 0:
            raise ImitateError(
                f"max_joint_acceleration {self.max_joint_acceleration} not accepted: > 0 rad/s^2"
            )
        if self.max_iter < 0 or self.patience < 1 or not self.tol >= 0:
            raise ImitateError(
                f"max_iter >= 0, patience >= 1 and tol >= 0 needed; got {self.max_iter}, "
                f"{self.patience}, {self.tol}"
            )

    def replace(self, **settings) -> PlanConfig:
        """These settings with ``settings`` (field names and values) replaced.

        Raises:
            ImitateError: a name that is no field (the message lists them), or a bad value.
        """
        names = tuple(f.name for f in dataclasses.fields(self))
        unknown = sorted(set(settings) - set(names))
        if unknown:
            raise ImitateError(f"plan setting(s) {unknown} unknown; accepted: {names}")
        return dataclasses.replace(self, **settings)
