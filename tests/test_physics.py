"""The physics itself: a collision-free rest pose, firm hands, liquid that stays and pours."""

import mujoco
import numpy as np
import pytest

from imitate.envs import assembly, mannequin
from imitate.envs.bimanual import inside
from imitate.envs.collision import signed_distances
from imitate.envs.pour.env import PouringEnv
from imitate.envs.pour.geometry import PourGeometry
from imitate.envs.pour.liquid import Liquid, particle_bodies
from imitate.models import objects


@pytest.fixture(scope="module")
def env():
    env = PouringEnv(particles=60)
    yield env
    env.close()


def _hold_still(env, seconds):
    target = env.data.ctrl.copy()
    for _ in range(round(seconds / env.dt)):
        _, _, _, _, info = env.step(target)
    return info


def _fraction_in(env, body, shape):
    points = env.data.xpos[env._particle_bodies]
    return float(np.mean(inside(env.data, body, points)))


def test_rest_pose_is_collision_free(env):
    _, info = env.reset(seed=0)
    assert info["min_distance"] > 0.005
    info = _hold_still(env, 0.5)
    assert info["min_distance"] > 0.005
    assert info["reward_collision"] == 0.0


def test_hands_hold_pose_under_gravity(env):
    env.reset(seed=1)
    start = {
        b: env.data.body(b).xpos.copy() for b in ("right_hand", "left_hand", "bottle", "glass")
    }
    _hold_still(env, 2.0)
    for body, pos in start.items():
        drift = np.linalg.norm(env.data.body(body).xpos - pos)
        assert drift < 0.01, f"{body} drifted {drift * 1000:.1f} mm"


def test_particles_stay_in_upright_bottle(env):
    env.reset(seed=2)
    assert _fraction_in(env, objects.BOTTLE, objects.BOTTLE_SHAPE) == 1.0
    info = _hold_still(env, 2.0)
    assert _fraction_in(env, objects.BOTTLE, objects.BOTTLE_SHAPE) == 1.0
    assert info["spilled"] == 0


def _teacher_holding(particles):
    config = assembly.SceneConfig(contents=(Liquid(particles),), holder="teacher")
    model = assembly.build_model(config)
    data = mujoco.MjData(model)
    return model, data


def _tilted(angle):
    quat = np.zeros(4)
    mujoco.mju_axisAngle2Quat(quat, np.array([1.0, 0.0, 0.0]), -angle)  # neck towards +y
    return quat


def test_particles_leave_bottle_tilted_120_degrees():
    model, data = _teacher_holding(60)
    bottle_at = np.array([1.0, -0.1, 1.0])

    def pose(angle):
        hand_pos, hand_quat = mannequin.hand_pose_for_object(
            model, objects.BOTTLE, bottle_at, _tilted(angle)
        )
        mannequin.pose_arm(model, data, "left", hand_pos, hand_quat)

    pose(0.0)
    assembly.hold(model, data, "teacher")
    Liquid(60).reset(model, data, None)
    steps = 400
    for k in range(steps):  # tilt to 120 degrees in 0.8 s, then hold for 1 s
        pose(np.radians(120) * min(1.0, k / (0.8 / model.opt.timestep)))
        mujoco.mj_step(model, data)
    mujoco.mj_step(model, data, nstep=500)
    in_bottle = inside(data, objects.BOTTLE, data.xpos[particle_bodies(model)])
    assert in_bottle.mean() < 0.1


def test_glass_holds_poured_particles(env):
    """Particles dropped in a column above the glass end up, and stay, inside it."""
    env.reset(seed=3)
    glass = env.data.body(objects.GLASS)
    axis = glass.xmat.reshape(3, 3)[:, 2]
    n = len(env._particle_bodies)
    for i, body in enumerate(env._particle_bodies):
        joint = env.model.body_jntadr[body]
        adr = env.model.jnt_qposadr[joint]
        ring = 0.012 * np.array([np.cos(i * 2.4), np.sin(i * 2.4), 0.0])
        env.data.qpos[adr : adr + 3] = glass.xpos + (0.12 + 0.012 * (i // 4)) * axis + ring
    mujoco.mj_forward(env.model, env.data)
    _hold_still(env, 2.0)
    assert env.pour_fraction >= 0.95, f"{env.pour_fraction * n:.0f} of {n} in the glass"


class _Body:
    def __init__(self, pos):
        self.xpos, self.xmat = np.array(pos, float), np.eye(3).ravel()


class _Env:
    """What :class:`PourGeometry` reads of a ``PouringEnv``: the bottle upright above the glass,
    three particles, the last one still in the bottle."""

    dt = 0.01

    def __init__(self):
        bodies = {objects.BOTTLE: _Body((0.01, 0.0, 0.0)), objects.GLASS: _Body((0.0, 0.0, -0.2))}
        self.data = type("Data", (), {"body": staticmethod(bodies.__getitem__)})()
        self.positions = np.zeros((3, 3))
        self.in_bottle = np.zeros(3, bool)

    def particle_positions(self):
        return self.positions

    def particles_in(self, container):
        return self.in_bottle


def test_pour_geometry_counts_the_particles_that_left_the_bottle_where_they_cross_the_rim():
    geometry, env = PourGeometry(), _Env()
    rim = -0.2 + objects.GLASS_SHAPE.height
    env.positions[:] = [(0.01, 0.0, rim + 0.05), (0.06, 0.0, rim + 0.05), (0.0, 0.0, rim + 0.05)]
    env.in_bottle[:] = (False, False, True)
    geometry(env)
    assert geometry.summary()["stream_inside_share"] is None  # nothing crossed, nothing poured
    env.positions[:, 2] = rim - 0.05  # all three fall through the plane, one inside the bottle
    env.in_bottle[:] = (False, False, True)
    geometry(env)
    env.in_bottle[:] = False
    geometry(env)
    summary = geometry.summary()
    assert summary["stream_inside_share"] == 0.5  # 10 mm inside the rim, 60 mm outside
    assert summary["stream_offset_median_m"] == pytest.approx(0.035)
    assert summary["mouth_offset_median_m"] == pytest.approx(0.01)
    mouth = objects.BOTTLE_SHAPE.height - objects.GLASS_SHAPE.height + 0.2
    assert summary["mouth_above_rim_min_m"] == pytest.approx(mouth)
    assert summary["tilt_max_deg"] == 0.0 and summary["pour_seconds"] == pytest.approx(0.01)


def test_clearance_skips_only_pairs_mujoco_puts_beyond_its_reach():
    """The clearance leaves out the pairs whose bounding spheres lie further apart than
    ``distmax``: every distance is MuJoCo's own for every pair, in postures near and far."""
    env = PouringEnv(particles=0, obstacles=({"shape": "box", "pos": (0.55, 0.0, 0.70),
                                              "size": (0.03, 0.03, 0.05)},))
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    pairs, m, d = env._pairs, env.model, env.data
    skipped = 0
    for _ in range(20):
        env.step(np.clip(env.data.ctrl + rng.uniform(-0.3, 0.3, m.nu), env.action_space.low,
                         env.action_space.high).astype(np.float32))
        dist, _ = signed_distances(m, d, pairs)
        for k, (g1, g2) in enumerate(zip(pairs.geom1, pairs.geom2, strict=True)):
            assert dist[k] == mujoco.mj_geomDistance(m, d, int(g1), int(g2), 0.2, None)
        skipped += int(np.sum(dist == 0.2))
    assert skipped > 0  # the shortcut was taken

