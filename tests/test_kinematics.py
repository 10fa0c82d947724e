"""``Kinematics`` of the robot in the pouring scene: held objects follow the hands, point
Jacobians, their rates and signed-distance gradients against central finite differences."""

from __future__ import annotations

from dataclasses import replace

import mujoco
import numpy as np
import pytest

from imitate.envs import assembly
from imitate.errors import ImitateError
from imitate.models import humanoid, objects
from imitate.motion.kinematics import Kinematics

H = 1e-6  # central-difference step [rad]


@pytest.fixture(scope="module")
def kin():
    model = assembly.build_model(replace(assembly.SceneConfig(), holder="robot"))
    return Kinematics(model, humanoid.JOINTS, assembly.clearance_geoms(model))


def _posture(seed: int, n: int) -> np.ndarray:
    return humanoid.rest_pose() + np.random.default_rng(seed).uniform(-0.3, 0.3, n)


def _bodies_and_points(kin: Kinematics) -> tuple[list[int], np.ndarray]:
    """The two held objects and the right hand, each with a point fixed in its body frame."""
    names = (objects.BOTTLE, objects.GLASS, humanoid.RIGHT_HAND)
    bodies = [kin.model.body(name).id for name in names]
    local = np.array([[0.01, -0.02, 0.15], [0.03, 0.0, -0.05], [0.02, 0.01, 0.0]])
    return bodies, local


def _world(kin: Kinematics, bodies, local) -> np.ndarray:
    d = kin.data
    return np.array([
        d.xpos[b] + d.xmat[b].reshape(3, 3) @ p for b, p in zip(bodies, local, strict=True)
    ])


def test_held_objects_follow_the_hands(kin):
    bottle = kin.model.body(objects.BOTTLE).id
    kin.update(_posture(0, kin.n))
    before = kin.data.xpos[bottle].copy()
    kin.update(_posture(1, kin.n), held=False)
    np.testing.assert_array_equal(kin.data.xpos[bottle], before)  # left where it was
    kin.update(_posture(1, kin.n))
    assert np.linalg.norm(kin.data.xpos[bottle] - before) > 1e-3


def test_held_objects_are_placed_with_mujocos_arithmetic(kin):
    """update() composes a held object's pose with its hand's in a compiled kernel: the same
    bits as mju_rotVecQuat and mju_mulQuat."""
    m, d = kin.model, kin.data
    for seed in range(20):
        kin.update(_posture(seed, kin.n))
        for obj, (hand, rel_pos, rel_quat) in kin._held.items():
            adr = m.jnt_qposadr[m.body_jntadr[obj]]
            pos, quat = np.empty(3), np.empty(4)
            mujoco.mju_rotVecQuat(pos, rel_pos, d.xquat[hand])
            mujoco.mju_mulQuat(quat, d.xquat[hand], rel_quat)
            np.testing.assert_array_equal(d.qpos[adr : adr + 3], pos + d.xpos[hand])
            np.testing.assert_array_equal(d.qpos[adr + 3 : adr + 7], quat)


def test_update_between_is_update_at_the_interpolated_posture(kin):
    """The posture along a step, formed in a kernel, has NumPy's bits: the same poses."""
    rng = np.random.default_rng(3)
    for s in (0.5, 1 / 3, 0.9):
        qa, qb = _posture(int(rng.integers(100)), kin.n), _posture(int(rng.integers(100)), kin.n)
        kin.update_between(qa, qb, s)
        between = kin.data.geom_xpos.copy(), kin.data.xquat.copy()
        kin.update((1.0 - s) * qa + s * qb)
        np.testing.assert_array_equal(between[0], kin.data.geom_xpos)
        np.testing.assert_array_equal(between[1], kin.data.xquat)


def test_near_pair_bounds_skip_no_pair_within_range():
    """The capsule and slab bounds skip only pairs MuJoCo finds farther than ``distmax``: the
    same pairs and distances as measuring every pair, in a scene with a box and a cylinder."""
    obstacles = (
        assembly.Obstacle("box", (0.45, -0.17, 0.7), (0.05, 0.05, 0.09)),
        assembly.Obstacle("cylinder", (0.45, 0.17, 0.7), (0.04, 0.09)),
    )
    config = replace(assembly.SceneConfig(), holder="robot", obstacles=obstacles)
    model = assembly.build_model(config)
    kin = Kinematics(model, humanoid.JOINTS, assembly.clearance_geoms(model))
    distmax, fromto, measured = 0.05, np.zeros(6), 0
    for seed in range(40):
        kin.update(humanoid.rest_pose() + np.random.default_rng(seed).uniform(-0.6, 0.6, kin.n))
        everything = {}
        for p, (g1, g2) in enumerate(zip(kin.pairs.geom1, kin.pairs.geom2, strict=True)):
            value = mujoco.mj_geomDistance(model, kin.data, g1, g2, distmax, fromto)
            if value < distmax:
                everything[p] = value
        near = kin.distances(distmax)
        assert dict(zip(near.pairs.tolist(), near.dist.tolist(), strict=True)) == everything
        measured += len(everything)
    assert measured > 40


def test_planning_model_is_the_whole_scene_bit_for_bit():
    """The planner's model (clearance geoms only, no teacher) gives the whole scene's poses,
    Jacobians, Jacobian rates and distances, bit for bit, with an obstacle and a cylinder."""
    obstacles = (assembly.Obstacle("cylinder", (0.45, 0.0, 0.72), (0.04, 0.09)),)
    config = replace(assembly.SceneConfig(), obstacles=obstacles)
    whole_model = assembly.build_model(replace(config, holder="robot"))
    models = (whole_model, assembly.planning_model(config))
    assert models[1].ngeom < models[0].ngeom / 4 and models[1].nbody < models[0].nbody
    kins = [Kinematics(m, humanoid.JOINTS, assembly.clearance_geoms(m)) for m in models]
    bodies = [objects.BOTTLE, objects.GLASS, humanoid.RIGHT_HAND, humanoid.LEFT_HAND]
    geoms = [models[1].geom(g).name for g in assembly.clearance_geoms(models[1])]
    found = 0
    for seed in range(20):
        q = humanoid.rest_pose() + np.random.default_rng(seed).uniform(-0.5, 0.5, kins[0].n)
        seen = []
        for kin in kins:
            kin.update(q)
            ids = [kin.model.body(b).id for b in bodies]
            points = kin.data.xpos[ids] + 0.1
            near = kin.distances(0.05, jacobian=True)
            seen.append((
                kin.data.xpos[ids], kin.data.xquat[ids],
                np.array([kin.data.geom(g).xpos for g in geoms]),
                kin.point_jacobians(ids, points),
                kin.point_jacobian_rates(ids, points, np.linspace(-1.0, 1.0, kin.n)),
                [kin.pairs.names(kin.model, p) for p in near.pairs], near.dist, near.jac,
            ))
        for whole, planning in zip(*seen, strict=True):
            np.testing.assert_array_equal(whole, planning)
        found += len(seen[0][-2])
    assert found > 5


def test_point_jacobians_and_rates_match_finite_differences(kin):
    bodies, local = _bodies_and_points(kin)
    q = _posture(2, kin.n)
    kin.update(q)
    points = _world(kin, bodies, local)
    jac = kin.point_jacobians(bodies, points)
    for i, jac_i in enumerate(jac):
        alone = kin.point_jacobians(bodies[i : i + 1], points[i : i + 1])
        np.testing.assert_array_equal(alone[0], jac_i)
    fd = np.empty_like(jac)
    for j, e in enumerate(np.eye(kin.n) * H):
        kin.update(q + e)
        plus = _world(kin, bodies, local)
        kin.update(q - e)
        fd[:, :, j] = (plus - _world(kin, bodies, local)) / (2 * H)
    np.testing.assert_allclose(jac, fd, atol=1e-7)

    b = np.random.default_rng(2).normal(size=kin.n)
    kin.update(q)
    kin.update(q + 0.1, held=False)
    kin.update(q, held=False)  # robot-only update: enough for the rates
    rates = kin.point_jacobian_rates(bodies, points, b)
    jacs = []
    for sign in (1.0, -1.0):
        kin.update(q + sign * H * b)
        jacs.append(kin.point_jacobians(bodies, _world(kin, bodies, local)))
    np.testing.assert_allclose(rates, (jacs[0] - jacs[1]) / (2 * H), atol=1e-6)


def test_distance_gradient_matches_finite_differences(kin):
    rng = np.random.default_rng(2)
    checked = 0
    for _ in range(5):
        q = humanoid.rest_pose() + rng.uniform(-0.3, 0.3, kin.n)
        kin.update(q)
        near = kin.distances(0.05, jacobian=True)
        for k, pair in enumerate(near.pairs):
            fd = np.zeros(kin.n)
            for i in range(kin.n):
                e = np.zeros(kin.n)
                e[i] = H
                vals = []
                for sign in (1, -1):
                    kin.update(q + sign * e)
                    full = kin.distances(0.2)
                    vals.append(full.dist[full.pairs == pair][0])
                fd[i] = (vals[0] - vals[1]) / (2 * H)
            np.testing.assert_allclose(near.jac[k], fd, atol=1e-4)
            checked += 1
    assert checked > 0


def test_bad_input_raises(kin):
    with pytest.raises(ImitateError, match="unknown"):
        Kinematics(kin.model, ("no_such_joint",))
    free = next(
        kin.model.joint(j).name for j in range(kin.model.njnt)
        if kin.model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE
    )
    with pytest.raises(ImitateError, match="not a hinge"):
        Kinematics(kin.model, (free,))
    with pytest.raises(ImitateError, match="geoms"):
        Kinematics(kin.model, humanoid.JOINTS).distances(0.1)
