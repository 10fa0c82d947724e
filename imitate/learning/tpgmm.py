r"""TP-GMM (Calinon, "A tutorial on task-parameterized movement learning and retrieval", 2016):
the demonstrations learned in every candidate frame at once, reproduced in a new scene by the
product of the frames' Gaussians, component by component, then GMR.

A :class:`FrameModel` is a model learned in candidate **frames**: a task space of
:class:`~imitate.taskspace.Relative` terms (the tool relative to the target, each held object
relative to each place of the scene) and the objects' :class:`~imitate.taskspace.Angles`: one
GMM over time and all of them (the frames side by side, one responsibility per sample as TP-GMM
shares it). The world is no frame: the teacher's is not the robot's (the demonstrations' world
positions are where the teacher stood). In a scene whose places stand at ``origins``,
:meth:`FrameModel.at` makes each component's experts: for each term ``j`` its columns given
time, ``X_j | t ~ N(a_j + b_j (t - mu_t), C_j)``, read as a statement on the reproduction ``z``
(in :attr:`FrameModel.space`): ``H_j z = X_j - o_j`` (``H_j`` takes ``p_of - p_to`` from ``z``;
``o_j`` is the places' part). Their product (:func:`product`) is the component in ``z`` given
time, ``N(alpha + beta (t - mu_t), Lambda^-1)``; with the component's own time marginal it is a
Gaussian over ``(t, z)``, and GMR of those components gives mean and covariance over time.
Time is conditioned on rather than multiplied once per frame (as the tutorial's ``(t, x)``
frames would count it), so the product sharpens space, not time.

The reproduction's space (:func:`reproduction_space`) holds the tool relative to the target (so
a task's critical phase and eq. 21's diagonal read that relation) and the target relative to the
first place (where the scene has one), then the angles; without a place it is eq. 1.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from imitate.errors import ImitateError
from imitate.learning.gmm import GMM
from imitate.learning.gmr import gmr
from imitate.learning.model import LearnedModel
from imitate.taskspace import OBJECTS, Angles, Relative, TaskSpace

__all__ = ["FrameModel", "product", "reproduction_space"]

_TOOL, _TARGET = OBJECTS


def reproduction_space(places: Sequence[str]) -> TaskSpace:
    """The space a model in frames over ``places`` is reproduced in: the tool relative to the
    target, the target relative to the first place (if any), the angles."""
    anchor = (Relative(_TARGET, places[0]),) if places else ()
    return TaskSpace((Relative(_TOOL, _TARGET), *anchor, Angles(_TOOL), Angles(_TARGET)))


def product(
    maps: Sequence[np.ndarray], means: Sequence[np.ndarray], covariances: Sequence[np.ndarray]
) -> tuple[np.ndarray, np.ndarray]:
    """The product of Gaussian experts on ``z``: expert ``j`` says ``H_j z ~ N(mu_j, C_j)``.

    Args:
        maps: ``H_j`` ``(k_j, d)``; together of rank ``d``.
        means: ``mu_j`` ``(k_j,)`` or ``(k_j, n)`` (``n`` right-hand sides at once).
        covariances: ``C_j`` ``(k_j, k_j)``, positive definite.

    Returns:
        ``(mean, covariance)``: ``Lambda^-1 sum_j H_j^T C_j^-1 mu_j`` (``(d,)`` or ``(d, n)``)
        and ``Lambda^-1`` ``(d, d)``, ``Lambda = sum_j H_j^T C_j^-1 H_j``.

    Raises:
        ImitateError: the experts leave a direction of ``z`` undetermined.
    """
    precision = sum(H.T @ np.linalg.solve(C, H) for H, C in zip(maps, covariances, strict=True))
    information = sum(H.T @ np.linalg.solve(C, mu)
                      for H, mu, C in zip(maps, means, covariances, strict=True))
    if np.linalg.matrix_rank(precision) < len(precision):
        raise ImitateError(f"the experts determine {np.linalg.matrix_rank(precision)} of "
                           f"{len(precision)} directions: a frame of each object is missing")
    covariance = np.linalg.inv(precision)
    return covariance @ information, (covariance + covariance.T) / 2


@dataclass(frozen=True)
class FrameModel:
    """A model learned in candidate frames, reproduced by TP-GMM's product (module docstring).

    Attributes:
        model: Learned over time and ``frames``' columns.
        frames: The candidate frames: :class:`~imitate.taskspace.Relative` terms (those of
            :attr:`space` among them) and both objects' :class:`~imitate.taskspace.Angles`.
    """

    model: LearnedModel
    frames: TaskSpace

    def __post_init__(self) -> None:
        needed = {*self.space.terms} - {*self.frames.terms}
        if needed:
            raise ImitateError(f"TP-GMM's frames need {sorted(map(str, needed))}; got "
                               f"{self.frames.text}")

    @property
    def places(self) -> tuple[str, ...]:
        """The places the frames name (the origins :meth:`at` needs)."""
        return self.frames.places

    @property
    def space(self) -> TaskSpace:
        """The space it is reproduced in (:func:`reproduction_space`)."""
        return reproduction_space(self.places)

    def at(self, origins: Mapping[str, np.ndarray]) -> LearnedModel:
        """The reproduction in :attr:`space` in a scene whose places stand at ``origins``
        (name -> ``(3,)`` [m], world frame; every one of :attr:`places`): GMM (the product per
        component), its GMR over the model's times (eq. 18), the data in :attr:`space`.

        Raises:
            ImitateError: a place without its origin.
        """
        missing = sorted(set(self.places) - set(origins))
        if missing:
            raise ImitateError(f"no origin of the places {missing}; given: {sorted(origins)}")
        experts = [self._expert(term, origins) for term in self.frames.terms]
        g = self.model.gmm
        means, covariances = [], []
        for mean, cov in zip(g.means_, g.covariances_, strict=True):
            cond = [_given_time(mean, cov, self.frames.columns(term)) for term in self.frames.terms]
            rhs = [np.column_stack((a - offset, b))
                   for (a, b, _), (_, offset) in zip(cond, experts, strict=True)]
            fused, spread = product([H for H, _ in experts], rhs, [c for *_, c in cond])
            alpha, beta, var_t = fused[:, 0], fused[:, 1], cov[0, 0]
            means.append(np.concatenate(([mean[0]], alpha)))
            covariances.append(np.block([
                [np.array([[var_t]]), var_t * beta[None]],
                [var_t * beta[:, None], spread + var_t * np.outer(beta, beta)],
            ]))
        gmm = GMM.from_parameters(g.weights_, np.array(means), np.array(covariances))
        mean, covariance = gmr(gmm, self.model.times)
        columns = np.concatenate([[0], 1 + self.frames.part_columns(self.space)])
        return LearnedModel(
            data=self.model.data[:, columns], gmm=gmm, bic_curve=self.model.bic_curve,
            times=self.model.times, mean=mean, covariance=covariance, alignment=None,
        )

    def _expert(self, term: Relative | Angles, origins: Mapping[str, np.ndarray]
                ) -> tuple[np.ndarray, np.ndarray]:
        """``(H (k, m), o (k,))`` of ``term``: its value is ``H z + o`` for ``z`` in
        :attr:`space` (``o``: the places' part)."""
        space = self.space
        if isinstance(term, Angles):
            H = np.zeros((2, space.m))
            H[:, space.columns(term)] = np.eye(2)
            return H, np.zeros(2)
        # each position as S z + c: the target at the first place plus its relation to it (at
        # 0 without a place: only relations to it are then in the frames), the tool at the
        # target plus theirs, a place at its origin
        relation = np.zeros((3, space.m))
        relation[:, space.columns(space.terms[0])] = np.eye(3)
        target = np.zeros((3, space.m))
        anchor = np.zeros(3)
        if self.places:
            target[:, space.columns(space.terms[1])] = np.eye(3)
            anchor = np.asarray(origins[self.places[0]], dtype=float)
        H, offset = np.zeros((3, space.m)), np.zeros(3)
        for name, sign in ((term.of, 1.0), (term.to, -1.0)):
            if name in OBJECTS:
                H += sign * (target + relation if name == _TOOL else target)
                offset += sign * anchor
            else:
                offset += sign * np.asarray(origins[name], dtype=float)
        return H, offset


def _given_time(mean: np.ndarray, cov: np.ndarray, columns: slice
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A component's ``columns`` (of the space after time) given time: ``(a, b, C)`` of
    ``N(a + b (t - mu_t), C)``."""
    cols = np.arange(columns.start, columns.stop) + 1
    slope = cov[cols, 0] / cov[0, 0]
    return mean[cols], slope, cov[np.ix_(cols, cols)] - np.outer(slope, cov[0, cols])

