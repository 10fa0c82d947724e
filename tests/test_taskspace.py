"""Task space (eq. 1): values, unwrapping, robot-side Jacobian against finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from imitate.errors import ImitateError
from imitate.taskspace import (
    ObjectKinematics,
    gaze_frame,
    object_orientation,
    task_space,
    task_state,
)

NV = 6


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    return Rotation.from_rotvec(axis * angle).as_matrix()


class _Chain:
    """Serial chain of hinge joints with random axes and link offsets (a toy arm)."""

    def __init__(self, rng: np.random.Generator, base_rotation: np.ndarray):
        self.axes = rng.normal(size=(NV, 3))
        self.axes /= np.linalg.norm(self.axes, axis=1, keepdims=True)
        self.offsets = rng.normal(scale=0.2, size=(NV, 3))
        self.base_rotation = base_rotation
        self.base = rng.normal(size=3)
        self.local_axis = np.array([0.0, 0.0, 1.0])

    def kinematics(self, q: np.ndarray) -> ObjectKinematics:
        R, p = self.base_rotation, self.base.copy()
        joint_axes, origins = [], []
        for i in range(NV):
            joint_axes.append(R @ self.axes[i])
            origins.append(p.copy())
            R = R @ _rot(self.axes[i], q[i])
            p = p + R @ self.offsets[i]
        z = np.array(joint_axes).T  # (3, nv): world-frame joint axes
        jac_pos = np.cross(z.T, p - np.array(origins)).T
        return ObjectKinematics(p, R @ self.local_axis, jac_pos, z)


def _finite_difference(bottle, glass, gaze, q, h=1e-6):
    x0, _ = task_state(bottle.kinematics(q), glass.kinematics(q), gaze)
    ref = x0[[3, 5]]
    J = np.empty((7, NV))
    for i in range(NV):
        dq = np.zeros(NV)
        dq[i] = h
        xp, _ = task_state(bottle.kinematics(q + dq), glass.kinematics(q + dq), gaze, angle_ref=ref)
        xm, _ = task_state(bottle.kinematics(q - dq), glass.kinematics(q - dq), gaze, angle_ref=ref)
        J[:, i] = (xp - xm) / (2 * h)
    return J


@pytest.mark.parametrize("seed", range(8))
def test_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    gaze = Rotation.random(random_state=seed).as_matrix()
    bottle = _Chain(rng, Rotation.random(random_state=seed + 100).as_matrix())
    glass = _Chain(rng, Rotation.random(random_state=seed + 200).as_matrix())
    q = rng.uniform(-np.pi, np.pi, NV)
    _, J = task_state(bottle.kinematics(q), glass.kinematics(q), gaze)
    np.testing.assert_allclose(J, _finite_difference(bottle, glass, gaze, q), atol=2e-6, rtol=1e-6)


@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_jacobian_and_branch_at_the_angle_wrap(side):
    rng = np.random.default_rng(11)
    bottle = _Chain(rng, np.eye(3))
    glass = _Chain(rng, np.eye(3))
    q = rng.uniform(-1, 1, NV)
    a = bottle.kinematics(q).axis
    forward = np.cross(a, rng.normal(size=3))
    forward /= np.linalg.norm(forward)
    # Camera right pointing against the projected axis, turned by 1e-7 rad: angle ~ +-(pi - 1e-7).
    right = _rot(forward, side * 1e-7) @ -a
    gaze = np.column_stack((right, np.cross(forward, right), forward))
    x, J = task_state(bottle.kinematics(q), glass.kinematics(q), gaze)
    assert abs(abs(x[3]) - np.pi) < 1e-6
    np.testing.assert_allclose(J, _finite_difference(bottle, glass, gaze, q), atol=2e-6, rtol=1e-6)
    x_ref, _ = task_state(
        bottle.kinematics(q), glass.kinematics(q), gaze, angle_ref=[x[3] + 2 * np.pi, 0.0]
    )
    np.testing.assert_allclose(x_ref[3], x[3] + 2 * np.pi)


def test_singular_axis_along_gaze_holds_reference_and_zeroes_the_row():
    rng = np.random.default_rng(3)
    bottle, glass = _Chain(rng, np.eye(3)), _Chain(rng, np.eye(3))
    q = rng.uniform(-1, 1, NV)
    a = bottle.kinematics(q).axis
    gaze = gaze_frame(a, up=rng.normal(size=3))  # looking straight along the bottle's axis
    x, J = task_state(bottle.kinematics(q), glass.kinematics(q), gaze, angle_ref=[0.7, 0.0])
    assert x[3] == pytest.approx(0.7)
    np.testing.assert_array_equal(J[3], 0.0)
    np.testing.assert_allclose(x[4], 1.0)
    assert np.all(np.isfinite(J))


def test_batched_state_equals_per_sample_state():
    rng = np.random.default_rng(5)
    bottle, glass = _Chain(rng, np.eye(3)), _Chain(rng, np.eye(3))
    gaze = Rotation.random(random_state=5).as_matrix()
    qs = rng.uniform(-2, 2, (4, NV))
    kb = [bottle.kinematics(q) for q in qs]
    kg = [glass.kinematics(q) for q in qs]

    def stack(ks):
        return ObjectKinematics(*(np.stack([getattr(k, f) for k in ks]) for f in
                                  ("position", "axis", "jac_pos", "jac_rot")))

    x, J = task_state(stack(kb), stack(kg), gaze)
    for n in range(4):
        xn, Jn = task_state(kb[n], kg[n], gaze)
        np.testing.assert_allclose(x[n], xn)
        np.testing.assert_allclose(J[n], Jn)


def test_task_space_matches_robot_side_and_unwraps():
    gaze = gaze_frame([1.0, 0.0, 0.0])
    n = 200
    turn = np.linspace(0.0, 3 * 2 * np.pi, n)  # three full turns around the gaze
    a_b = np.column_stack((np.full(n, 0.3), -np.cos(turn), np.sin(turn)))
    a_b /= np.linalg.norm(a_b, axis=1, keepdims=True)
    a_g = np.tile([0.0, 0.0, 1.0], (n, 1))
    p_b = np.column_stack((np.linspace(0, 1, n), np.zeros(n), np.ones(n)))
    p_g = np.zeros((n, 3))
    x = task_space(p_b, a_b, p_g, a_g, gaze)
    np.testing.assert_allclose(np.diff(x[:, 3]), np.diff(turn), atol=1e-12)
    np.testing.assert_allclose(x[:, :3], p_b - p_g)
    np.testing.assert_allclose(x[:, 4], a_b @ gaze[:, 2])
    np.testing.assert_allclose(x[:, 5], np.pi / 2)
    zeros = np.zeros((n, 3, 1))
    xr, _ = task_state(
        ObjectKinematics(p_b, a_b, zeros, zeros),
        ObjectKinematics(p_g, a_g, zeros, zeros),
        gaze,
        angle_ref=x[:, [3, 5]],
    )
    np.testing.assert_allclose(xr, x, atol=1e-12)


def test_task_space_holds_angle_through_singular_samples():
    gaze = gaze_frame([1.0, 0.0, 0.0])
    a = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    a_start = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    p = np.zeros((4, 3))
    x = task_space(p, a, p, a, gaze)
    np.testing.assert_allclose(x[:3, 3], np.pi / 2)
    x2 = task_space(p[:2], a_start, p[:2], a_start, gaze)
    np.testing.assert_allclose(x2[:, 3], np.pi / 2)  # leading undefined sample takes the next


def test_object_orientation_conventions():
    gaze = gaze_frame([0.0, 1.0, 0.0])  # looking along +y: right = +x, up = +z
    angle, along, defined = object_orientation([[1, 0, 0], [0, 0, 2], [0, 1, 0]], gaze)
    np.testing.assert_allclose(gaze, [[1, 0, 0], [0, 0, 1], [0, 1, 0]], atol=1e-15)
    assert np.linalg.det(gaze) == pytest.approx(-1.0)
    np.testing.assert_allclose(angle[:2], [0.0, np.pi / 2])
    np.testing.assert_allclose(along, [0.0, 0.0, 1.0], atol=1e-15)
    assert defined.tolist() == [True, True, False]


def test_bad_input_is_rejected():
    p = np.zeros((3, 3))
    a = np.tile([0.0, 0.0, 1.0], (3, 1))
    gaze = np.eye(3)
    with pytest.raises(ImitateError, match="orthonormal"):
        task_space(p, a, p, a, np.diag([1.0, 2.0, 1.0]))
    with pytest.raises(ImitateError, match=r"p_glass must have shape \(3, 3\)"):
        task_space(p, a, p[:2], a, gaze)
    with pytest.raises(ImitateError, match="finite"):
        task_space(np.full((3, 3), np.nan), a, p, a, gaze)
    with pytest.raises(ImitateError, match="non-zero"):
        task_space(p, np.zeros((3, 3)), p, a, gaze)
    with pytest.raises(ImitateError, match="unit vector"):
        ObjectKinematics(np.zeros(3), np.ones(3), np.zeros((3, 2)), np.zeros((3, 2)))
    with pytest.raises(ImitateError, match="jac_rot must have the shape"):
        ObjectKinematics(np.zeros(3), [0, 0, 1.0], np.zeros((3, 2)), np.zeros((3, 4)))
    k = ObjectKinematics(np.zeros(3), [0, 0, 1.0], np.zeros((3, 2)), np.zeros((3, 2)))
    with pytest.raises(ImitateError, match=r"angle_ref must have shape \(2,\)"):
        task_state(k, k, gaze, angle_ref=[0.0])
    with pytest.raises(ImitateError, match="parallel"):
        gaze_frame([0.0, 0.0, 2.0])
