"""The scripted teacher: seeded, right lengths and spreads, stillness between demonstrations;
the misaligned, misleading and coupled variations, and their pours in physics."""

import numpy as np
import pytest

from imitate.envs.mannequin import _cross
from imitate.envs.observation import tracked_point
from imitate.envs.pour.outcome import SUCCESS_FRACTION
from imitate.envs.pour.teacher import SCRIPT, teacher_pour
from imitate.envs.teacher_motion import TeacherConfig, script_demonstrations
from imitate.errors import ImitateError

_WAYPOINTS, _SWING_ROWS, _POUR_ROWS = SCRIPT.waypoints, SCRIPT.swing_rows, SCRIPT.agree_rows


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


def _spread_by_phase(motion, phases):
    """Per phase ``u``: the standard deviation over the demonstrations of the bottle's tracked
    point relative to the glass's ``(3,)`` [m] and of the bottle's tilt [deg]."""
    grid = np.linspace(0.0, 1.0, motion.warps.shape[1])
    spread = {}
    for u in phases:
        rel, tilt = [], []
        for demo, (start, end) in enumerate(motion.boundaries):
            t = start + (end - start) * np.interp(u, motion.warps[demo], grid)
            poses = motion.poses(np.array([t]))
            bottle, axis = tracked_point("bottle", *poses["bottle"])
            glass, _ = tracked_point("glass", *poses["glass"])
            rel.append((bottle - glass)[0])
            tilt.append(np.degrees(np.arccos(axis[0, 2])))
        spread[u] = (np.std(rel, axis=0), np.std(tilt))
    return spread


SWING, POUR = (0.12, 0.2), (0.55, 0.6, 0.65)  # phases of the swing and of the pour


@pytest.mark.parametrize("seed", [0, 3, 11])
def test_misaligned_teacher_varies_in_the_pour_and_agrees_in_the_swing(seed):
    """The aligned teacher varies by centimetres in the swing and by millimetres in the pour;
    the misaligned one the other way round: the swing the same in every demonstration (up to the
    tilt plane's azimuth, under a millimetre), the pour spread along the stream (world y)."""
    quiet = dict(seed=seed, tremor=0.0, tremor_angle=0.0)
    spread = {
        v: _spread_by_phase(script_demonstrations(TeacherConfig(variation=v, **quiet)),
                            SWING + POUR)
        for v in ("aligned", "misaligned")
    }
    swing = {v: max(s[u][0].max() for u in SWING) for v, s in spread.items()}
    pour = {v: min(s[u][0].max() for u in POUR) for v, s in spread.items()}
    assert swing["aligned"] > 0.02 and pour["aligned"] < 0.01
    assert swing["misaligned"] < 0.001 and max(s[1] for s in spread["misaligned"].values()) < 1.5
    assert pour["misaligned"] > 0.014  # offsets evenly over +-25 mm: a std of 17.7 mm
    assert all(np.argmax(spread["misaligned"][u][0]) == 1 for u in POUR)  # along the stream


def _beside_aligned(variation: str):
    """The aligned session of seed 5 and the ``variation`` one, checked to share the timing, the
    tremor, the tilt planes and the glass's path."""
    aligned, varied = (
        script_demonstrations(TeacherConfig(seed=5, variation=v)) for v in ("aligned", variation)
    )
    for name in ("boundaries", "warps", "tilt_planes", "tremor"):
        assert np.array_equal(getattr(aligned, name), getattr(varied, name)), name
    t = np.linspace(0.0, aligned.duration, 500)
    assert np.array_equal(aligned.poses(t)["glass"][0], varied.poses(t)["glass"][0])
    return aligned, varied


def test_misaligned_offsets_are_bounded_and_move_only_the_bottle():
    """Same seed, same session but for where the bottle's mouth is: the timing, the tremor, the
    tilt planes and the glass are the aligned teacher's; the mouth's offsets along the stream while
    pouring are evenly spread over +-offset and centred."""
    aligned, misaligned = _beside_aligned("misaligned")
    u = [_WAYPOINTS[row][0] for row in _POUR_ROWS]
    nominal = [_WAYPOINTS[row][3][1] for row in _POUR_ROWS]
    offsets = np.array([path(u)[:, 5] - nominal for path in misaligned.paths])
    np.testing.assert_allclose(offsets[:, 0], offsets[:, 1], atol=1e-15)
    np.testing.assert_allclose(np.sort(offsets[:, 0]), np.linspace(-0.025, 0.025, 5), atol=1e-15)


def test_aligned_teacher_is_the_teacher_before_the_variation_setting():
    """The default (aligned) session of seed 0 is, bit for bit up to rounding, what the teacher
    drew before ``variation`` existed (the default run's demonstrations)."""
    motion = script_demonstrations(TeacherConfig(seed=0, variation="aligned"))
    t = np.array([1.0, 3.0, 4.5, 6.0, 9.0, 14.0, 20.0])
    before = [
        [1.2098355976798763, -0.13039172858613546, 1.0502258461083096],
        [1.126466798202895, -0.20428727321995976, 1.2636832344274953],
        [1.1601217668951938, -0.3275471749258018, 1.3227508777820258],
        [1.1825324854042272, -0.15755842676344603, 1.0102386394544614],
        [1.079100695054475, -0.22809636681419881, 1.117320379710604],
        [0.7161447564857176, -0.00602162687857729, 1.1720215629769328],
        [1.1252802701796776, -0.22262212259609707, 1.178313893172592],
    ]
    np.testing.assert_allclose(motion.poses(t)["bottle"][0], before, rtol=1e-12, atol=0)
    assert motion.duration == pytest.approx(30.15467246576906, abs=1e-12)


def test_misaligned_demonstrations_still_pour_with_little_margin():
    """In physics with the liquid, the outermost pours (25 mm either side along the stream) put
    at least SUCCESS_FRACTION of it into the glass; 35 mm either side spills."""
    outer = {}
    for offset in (0.025, 0.035):
        motion = script_demonstrations(
            TeacherConfig(seed=0, variation="misaligned", offset=offset)
        )
        y = np.array([path(0.6)[5] for path in motion.paths])
        outer[offset] = [teacher_pour(motion, int(d)) for d in (np.argmin(y), np.argmax(y))]
    assert min(outer[0.025]) >= SUCCESS_FRACTION, outer
    assert min(outer[0.035]) < SUCCESS_FRACTION, outer


def test_bad_variation_is_refused():
    with pytest.raises(ImitateError, match="variation='sideways' not accepted"):
        TeacherConfig(variation="sideways")


def test_misleading_teacher_tilts_apart_only_while_pouring():
    """Same seed, same session as the aligned teacher but for the bottle's tilt while pouring:
    offset evenly over +-12 deg and centred; the glass and everything else the same."""
    aligned, misleading = _beside_aligned("misleading")
    u = [_WAYPOINTS[row][0] for row in _POUR_ROWS]
    tilt = np.degrees([path(u)[:, 7] - other(u)[:, 7]
                       for path, other in zip(misleading.paths, aligned.paths, strict=True)])
    np.testing.assert_allclose(np.sort(tilt[:, 0]), np.linspace(-12.0, 12.0, 5), atol=1e-12)
    np.testing.assert_allclose(tilt[:, 0], tilt[:, 1], atol=1e-12)
    swing = [_WAYPOINTS[row][0] for row in (1, 2, 7)]
    for path, other in zip(misleading.paths, aligned.paths, strict=True):
        np.testing.assert_array_equal(path(swing), other(swing))


@pytest.mark.parametrize(("variation", "seed", "column"), [("misleading", 2, 7), ("coupled", 3, 1)])
def test_varied_demonstrations_still_pour(variation, seed, column):
    """In physics with the liquid, the pours furthest apart along the variation's column (the
    bottle's tilt; the glass sideways, the bottle with it) put at least SUCCESS_FRACTION of it
    into the glass."""
    motion = script_demonstrations(TeacherConfig(seed=seed, variation=variation))
    apart = np.array([path(0.6)[column] for path in motion.paths])
    poured = [teacher_pour(motion, int(d)) for d in (np.argmin(apart), np.argmax(apart))]
    assert min(poured) >= SUCCESS_FRACTION, poured


def test_misleading_needs_a_declared_direction():
    with pytest.raises(ImitateError, match="task 'insert'.*no misleading direction"):
        TeacherConfig(task="insert", variation="misleading")


def test_coupled_teacher_moves_both_objects_together_only_while_pouring():
    """Same seed, same session as the aligned teacher but for where both objects are while
    pouring: the glass's bottom offset sideways (world y) evenly over +-40 mm at the pour's
    waypoints, the bottle with it; the bottle relative to the glass and everything else the
    same."""
    aligned, coupled = (script_demonstrations(TeacherConfig(seed=5, variation=v))
                        for v in ("aligned", "coupled"))
    for name in ("boundaries", "warps", "tilt_planes", "tremor"):
        assert np.array_equal(getattr(aligned, name), getattr(coupled, name)), name
    u = [_WAYPOINTS[row][0] for row in _POUR_ROWS]
    moved = np.array([path(u) - other(u) for path, other in zip(coupled.paths, aligned.paths,
                                                                 strict=True)])
    np.testing.assert_allclose(np.sort(moved[:, 0, 1]), np.linspace(-0.04, 0.04, 5), atol=1e-12)
    np.testing.assert_allclose(moved[:, 0, 1], moved[:, 1, 1], atol=1e-12)
    np.testing.assert_allclose(np.delete(moved, 1, axis=2), 0.0, atol=1e-12)
    t = np.linspace(0.0, aligned.duration, 500)
    poses = {v: m.poses(t) for v, m in (("aligned", aligned), ("coupled", coupled))}
    glass = {v: p["glass"][0] for v, p in poses.items()}
    relative = {v: p["bottle"][0] - glass[v] for v, p in poses.items()}
    np.testing.assert_allclose(relative["coupled"], relative["aligned"], atol=1e-12)
    assert np.abs(glass["coupled"] - glass["aligned"])[:, 1].max() > 0.039
    swing = [_WAYPOINTS[row][0] for row in (1, 2, 7)]
    for path, other in zip(coupled.paths, aligned.paths, strict=True):
        np.testing.assert_array_equal(path(swing), other(swing))


def test_coupled_needs_a_declared_axis():
    with pytest.raises(ImitateError, match="task 'marked'.*no coupled axis"):
        TeacherConfig(task="marked", variation="coupled")
