"""The scripted teacher: seeded, right lengths and spreads, stillness between demonstrations."""

import numpy as np
import pytest

from imitate.envs.observation import tracked_point
from imitate.envs.teacher_motion import (
    _SWING_ROWS,
    _WAYPOINTS,
    TeacherConfig,
    _cross,
    script_demonstrations,
)
from imitate.errors import ImitateError


def test_same_seed_same_motion_other_seed_other_motion():
    a, b, c = (script_demonstrations(TeacherConfig(seed=s)) for s in (4, 4, 5))
    t = np.linspace(0.0, a.duration, 200)
    assert np.array_equal(a.poses(t)["bottle"][0], b.poses(t)["bottle"][0])
    assert not np.allclose(a.poses(t)["bottle"][0], c.poses(t)["bottle"][0])


def test_durations_and_stillness_between_demonstrations():
    motion = script_demonstrations(TeacherConfig(seed=1))
    starts, ends = motion.boundaries.T
    assert len(starts) == 5
    assert np.all((ends - starts >= 4.0) & (ends - starts <= 5.0))
    assert (
        np.all(starts[1:] - ends[:-1] >= 1.0)
        and starts[0] >= 1.0
        and motion.duration - ends[-1] >= 1.0
    )
    # Held still between demonstrations: only tremor (a few mm) moves the objects.
    t = np.linspace(ends[0] + 0.01, starts[1] - 0.01, 50)
    for name, (pos, quat) in motion.poses(t).items():
        centre, _ = tracked_point(name, pos, quat)
        assert np.ptp(centre, axis=0).max() < 0.006


def test_time_warps_are_monotone_and_within_the_speed_variation():
    motion = script_demonstrations(TeacherConfig(seed=2, speed_variation=0.25))
    speed = np.diff(motion.warps, axis=1) * (motion.warps.shape[1] - 1)  # d phase / d (t / T)
    assert np.all(speed > 0)
    assert np.all(speed.max(axis=1) <= 1.25 / 0.75 + 1e-6)
    assert np.all(speed.max(axis=1) / speed.min(axis=1) > 1.2)  # the warps are not all flat


def test_spread_is_centimetres_while_transporting_and_millimetres_while_pouring():
    motion = script_demonstrations(TeacherConfig(n_demos=8, seed=3, tremor=0.0, tremor_angle=0.0))
    spread = {}
    for name, u in (("transport", 0.2), ("pour", 0.6)):
        rel, tilt = [], []
        for start, end in motion.boundaries:
            # The time at which this demonstration reaches phase u, from its warp.
            grid = np.linspace(0.0, 1.0, motion.warps.shape[1])
            t = start + (end - start) * np.interp(u, motion.warps[len(rel)], grid)
            poses = motion.poses(np.array([t]))
            bottle, axis = tracked_point("bottle", *poses["bottle"])
            glass, _ = tracked_point("glass", *poses["glass"])
            rel.append((bottle - glass)[0])
            tilt.append(np.degrees(np.arccos(axis[0, 2])))
        spread[name] = (np.std(rel, axis=0).max(), np.std(tilt))
    assert 0.01 < spread["transport"][0] < 0.08
    assert spread["pour"][0] < 0.012 and spread["pour"][1] < 5.0
    assert spread["pour"][0] < spread["transport"][0] / 2


@pytest.mark.parametrize("seed", [0, 7, 27])
def test_swings_spread_around_the_nominal_swing(seed):
    """The swings' offsets are centred over the session: every session's mean swing is the
    nominal one, while the swings themselves spread by centimetres."""
    motion = script_demonstrations(TeacherConfig(seed=seed))
    nominal = np.array(_WAYPOINTS[_SWING_ROWS[1]][3])
    mouths = np.array([path(_WAYPOINTS[_SWING_ROWS[1]][0])[4:7] for path in motion.paths])
    np.testing.assert_allclose(mouths.mean(axis=0), nominal, atol=1e-12)
    assert 0.02 < mouths[:, 0].std() < 0.12  # towards the robot: the 6 cm spread


def test_bottle_is_in_the_hand_the_robot_sees_on_its_right():
    motion = script_demonstrations(TeacherConfig(seed=0))
    poses = motion.poses(np.array([0.0]))
    assert poses["bottle"][0][0, 1] < 0 < poses["glass"][0][0, 1]  # robot's right is -y


@pytest.mark.parametrize(
    "kwargs", [{"n_demos": 0}, {"duration": (5.0, 4.0)}, {"speed_variation": 1.0}, {"tremor": -1.0}]
)
def test_bad_configs_are_refused(kwargs):
    with pytest.raises(ImitateError, match="not accepted"):
        TeacherConfig(**kwargs)


def test_the_posing_cross_product_is_numpys_bit_for_bit():
    rng = np.random.default_rng(0)
    for a, b in rng.normal(size=(1000, 2, 3)) * rng.lognormal(0, 3, size=(1000, 2, 1)):
        assert np.array_equal(_cross(a, b), np.cross(a, b))
