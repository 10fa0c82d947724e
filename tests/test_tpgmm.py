"""TP-GMM's product of Gaussians: hand-worked cases, and the frame the demonstrations agree in
deciding the reproduction, wherever the scene puts its places."""

from __future__ import annotations

import numpy as np
import pytest

from imitate.errors import ImitateError
from imitate.learning import LearningConfig, learn
from imitate.learning.tpgmm import FrameModel, product, reproduction_space
from imitate.taskspace import EQ1, Angles, Relative, TaskSpace

ANGLES = (Angles("tool"), Angles("target"))


def test_the_product_of_two_gaussians_by_hand():
    """``N(0, 1) N(2, 1) = N(1, 1/2)``; experts on ``a`` and on ``a + b``: ``a ~ N(1, 1)``,
    ``a + b ~ N(3, 1)`` give ``(a, b) = (1, 2)`` with precision ``[[2, 1], [1, 1]]``."""
    mean, cov = product([np.eye(1)] * 2, [np.array([0.0]), np.array([2.0])], [np.eye(1)] * 2)
    np.testing.assert_allclose(mean, [1.0])
    np.testing.assert_allclose(cov, [[0.5]])
    mean, cov = product([np.array([[1.0, 0.0]]), np.array([[1.0, 1.0]])],
                        [np.array([1.0]), np.array([3.0])], [np.eye(1)] * 2)
    np.testing.assert_allclose(mean, [1.0, 2.0])
    np.testing.assert_allclose(cov, [[1.0, -1.0], [-1.0, 2.0]])
    with pytest.raises(ImitateError, match="determine 1 of 2 directions"):
        product([np.array([[1.0, 0.0]])], [np.array([1.0])], [np.eye(1)])


def _demos(rng: np.random.Generator, n: int = 6, steps: int = 40) -> list[np.ndarray]:
    """Demonstrations in the frames of two places ``a`` and ``b``, each drawn anew per
    demonstration: the target held 20 cm over ``b`` (to 1 mm), the tool 10 cm beside and 30 cm
    over the target (to 1 mm); the target relative to ``a`` varies by decimetres."""
    frames = []
    for _ in range(n):
        a, b = rng.normal(0.0, 0.1, 3), rng.normal(0.0, 0.1, 3)
        target = b + [0.0, 0.0, 0.2] + rng.normal(0.0, 0.001, (steps, 3))
        tool = target + [0.1, 0.0, 0.3] + rng.normal(0.0, 0.001, (steps, 3))
        angles = rng.normal(0.0, 0.01, (steps, 4))
        frames.append(np.hstack((tool - target, tool - a, target - a, tool - b, target - b,
                                 angles)))
    return frames


FRAMES = TaskSpace((Relative("tool", "target"), Relative("tool", "a"), Relative("target", "a"),
                    Relative("tool", "b"), Relative("target", "b"), *ANGLES))


def test_the_frame_the_demonstrations_agree_in_places_the_reproduction():
    """Reproduced in the space of ``a`` (the first place), the target stands where ``b`` puts
    it, wherever ``a`` and ``b`` are, to millimetres; its spread there is the agreed frame's,
    not ``a``'s decimetres."""
    rng = np.random.default_rng(0)
    model = learn(_demos(rng), rate=10.0,
                  config=LearningConfig(n_components=2, use_dtw=False))
    framed = FrameModel(model, FRAMES)
    assert framed.space == TaskSpace((Relative("tool", "target"), Relative("target", "a"),
                                      *ANGLES))
    for a, b in ((np.zeros(3), np.zeros(3)), ([0.3, -0.2, 0.1], [-0.4, 0.5, 0.0])):
        reproduced = framed.at({"a": np.array(a), "b": np.array(b)})
        target = np.array(b) + [0.0, 0.0, 0.2] - a
        np.testing.assert_allclose(reproduced.mean[:, 3:6] - target, 0.0, atol=0.002)
        np.testing.assert_allclose(reproduced.mean[:, 0:3] - [0.1, 0.0, 0.3], 0.0, atol=0.002)
        assert np.sqrt(reproduced.variance[:, :6].max()) < 0.003
    plain = np.sqrt(model.variance[:, FRAMES.columns(Relative("target", "a"))].min())
    assert plain > 0.03  # the frame of a alone: decimetres apart


def test_without_a_place_it_is_eq_1_and_a_missing_frame_is_named():
    """No place: the reproduction's space is eq. 1, one expert per term, each its own columns:
    the GMR mean and variances are the model's (so eq. 21 plans as in the declared space; only
    the cross-covariances between terms are dropped); frames without the tool's relation to the
    target are refused, and an origin must be given."""
    assert reproduction_space(()) == EQ1
    rng = np.random.default_rng(1)
    model = learn([d[:, [0, 1, 2, 13, 14, 15, 16]] for d in _demos(rng)], rate=10.0,
                  config=LearningConfig(n_components=2, use_dtw=False))
    reproduced = FrameModel(model, EQ1).at({})
    np.testing.assert_allclose(reproduced.mean, model.mean, rtol=0, atol=1e-12)
    np.testing.assert_allclose(reproduced.variance, model.variance, rtol=1e-9, atol=1e-15)
    cross = np.abs(model.covariance[:, :3, 3:]).max()
    assert cross > 1e-12 and np.abs(reproduced.covariance[:, :3, 3:]).max() < 1e-9 * cross
    with pytest.raises(ImitateError, match="need"):
        FrameModel(model, TaskSpace((Relative("tool", "a"), *ANGLES)))
    with pytest.raises(ImitateError, match=r"no origin of the places \['a', 'b'\]"):
        FrameModel(learn(_demos(rng), rate=10.0, config=LearningConfig(
            n_components=2, use_dtw=False)), FRAMES).at({})
