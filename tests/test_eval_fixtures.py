"""Suite keys beyond the table: shelves and plates (fixtures placed where the weight-0
reproduction pours), the planner's null-space push as a switch, and the shipped suites that use
them; the variations of suites without them are drawn as before."""

import json

import mujoco
import numpy as np
import pytest

from imitate.demos.oracle import oracle_model
from imitate.envs.assembly import Fixture, SceneConfig
from imitate.envs.pour.task import pour_phase
from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.evaluation.suite import Suite, load_suite, named_suite
from imitate.evaluation.variation import (
    PLAN_KEYS,
    PLATE_SIZE,
    SHELF_SIZE,
    CriticalPlace,
    Variation,
    draw,
    free_places,
)
from imitate.learning import LearningConfig
from imitate.models import humanoid, objects
from imitate.models.scene import OBSTACLE_PREFIX
from imitate.motion import PlanConfig, plan_from_model
from imitate.motion.replay import planning_task
from imitate.taskspace import EQ1

POUR = get_task("pour")

MAX_ITER = 3  # a short optimization: the geometry is checked against the same plan
# The path the variations of test_eval draw with; the values below were drawn before the keys
# of this file existed.
PATH = np.array([[0.44, 0.0, 0.68], [0.45, 0.02, 0.67], [0.5, -0.1, 0.7]])
BEFORE = {
    ("default", 0, 0): dict(
        bottle_grasp=0.10095693498571634, glass_grasp=0.04348933568819351, particles=30,
        damping_scale=0.8012323250765667, replay_seeds=(1190382223, 72124473, 1642588604),
        obstacle_pos=(0.6553237963443994, 0.03053749402579603, 0.7048057939030214),
    ),
    ("default", 3, 7): dict(
        bottle_grasp=0.10457839260866658, glass_grasp=0.06000689091821749, particles=39,
        damping_scale=1.0975419361099212, replay_seeds=(48477729, 219436298, 1735958012),
        obstacle_pos=(0.4484912128883675, -0.034980530311237955, 0.6566380627484816),
    ),
    ("effort", 0, 2): dict(
        bottle_grasp=0.056465923133855, glass_grasp=0.050121889599679365, particles=57,
        damping_scale=0.9471224153931244, replay_seeds=(311600382,),
        path_length_weight=87.68236904759647,
    ),
    ("effort", 3, 11): dict(
        bottle_grasp=0.10465971679370732, glass_grasp=0.03441845892201433, particles=43,
        damping_scale=1.0212935279709514, replay_seeds=(1563024767,),
        path_length_weight=130.13954518753292,
    ),
}


@pytest.fixture(scope="module")
def teacher():
    """An oracle model, its gaze, its weight-0 plan (as ``free_places`` plans it) and places."""
    gaze = planning_task().gaze
    learned = oracle_model(gaze, learning=LearningConfig(k_max=6), rate=20.0)
    plan = plan_from_model(
        planning_task(SceneConfig(), gaze), learned, q0=humanoid.rest_pose(),
        config=PlanConfig(collision_weight=0.0, max_iter=MAX_ITER),
    )
    path, place = free_places(learned, gaze, MAX_ITER, POUR)
    return plan, path, place


@pytest.mark.parametrize("key", sorted(BEFORE))
def test_suites_without_the_new_keys_draw_as_before(key):
    name, seed, index = key
    v = draw(named_suite(name, POUR)[1], seed, index, PATH)
    expected = dict(BEFORE[key])
    pos = expected.pop("obstacle_pos", None)
    assert (v.obstacle.pos if v.obstacle else None) == pos
    assert {k: _value(v, k) for k in expected} == expected
    assert (v.shelf, v.plate, v.plan.nullspace_push) == (None, None, True)


def _value(v: Variation, key: str):
    """The variation's setting ``key``: the task's own, the planner's or its own field."""
    if key in v.options:
        return v.options[key]
    return getattr(v.plan, key) if key in PLAN_KEYS else getattr(v, key)


def _clearance(plan, fixture: Fixture, body: str, lift: float) -> float:
    """Smallest signed distance over the pouring steps of ``plan`` between ``body``'s hulls and
    ``fixture`` moved up by ``lift`` [m]."""
    moved = Fixture(fixture.shape, np.add(fixture.pos, (0, 0, lift)), fixture.size)
    kin = planning_task(SceneConfig(obstacles=(moved,))).kin
    m, d = kin.model, kin.data
    geom = m.geom(f"{OBSTACLE_PREFIX}0").id
    hulls = [g for g in range(m.ngeom) if m.geom(g).name.startswith(f"{body}_hull_")]
    closest = np.inf
    for q in plan.q[pour_phase(plan.mean, EQ1)]:
        kin.update(q)
        closest = min(closest, *(mujoco.mj_geomDistance(m, d, geom, h, 0.1, None) for h in hulls))
    return closest


def test_shelves_and_plates_stand_at_their_gaps_in_the_weight_0_pour(teacher):
    """Moved away by its gap and 1 mm, a shelf clears the bottle throughout the weight-0 pour
    and a plate the glass; by 1 mm less than the gap, each touches."""
    plan, path, place = teacher
    suite = Suite.default().replace(
        obstacle_share=0.0, shelf_share=1.0, plate_share=1.0, shelf_gap=[0.02, 0.10],
        plate_gap=[0.02, 0.03],
    )
    drawn = [draw(suite, 0, i, path, place) for i in range(2)]
    for v in drawn:
        assert v.shelf.size == SHELF_SIZE and v.plate.size == PLATE_SIZE
        assert 0.02 <= v.shelf_gap <= 0.10 and 0.02 <= v.plate_gap <= 0.03
        assert v.scene(POUR).obstacles == v.obstacles == (v.shelf, v.plate)
        for fixture, body, gap, up in ((v.shelf, objects.BOTTLE, v.shelf_gap, 1),
                                       (v.plate, objects.GLASS, v.plate_gap, -1)):
            assert _clearance(plan, fixture, body, up * (gap + 1e-3)) > 0
            assert _clearance(plan, fixture, body, up * (gap - 1e-3)) < 0
    assert drawn[0].shelf_gap != drawn[1].shelf_gap
    # each fixture's share and gap drawn whatever the other's share: the shelf stays put
    alone = draw(suite.replace(plate_share=0.0), 0, 0, path, place)
    assert (alone.shelf, alone.shelf_gap, alone.plate) == (drawn[0].shelf, drawn[0].shelf_gap, None)
    # and the keys of before keep their values
    before = draw(suite.replace(shelf_share=0.0, plate_share=0.0), 0, 0, path, place)
    assert before == Variation(**{
        **drawn[0].__dict__, "shelf": None, "shelf_gap": None, "plate": None, "plate_gap": None
    })


def test_a_fixture_in_the_robot_at_the_start_is_left_out(teacher):
    _, path, _ = teacher
    at_the_hand = CriticalPlace(  # the bottle's top at rest: the shelf would hold the hand
        tool_top=np.array([0.356, -0.18, 0.80]), target_bottom=np.array([0.30, -0.09, 0.59])
    )
    suite = Suite.default().replace(obstacle_share=0.0, shelf_share=1.0, plate_share=1.0)
    v = draw(suite, 0, 0, path, at_the_hand)
    assert v.shelf is None and v.shelf_gap is None and v.plate is not None


def test_a_suite_with_fixtures_needs_the_critical_place():
    suite = Suite.default().replace(shelf_share=0.5)
    with pytest.raises(ImitateError, match=r"shelf_share=0.5 plate_share=0.0 need the critical "
                       r"phase's place: pass draw\(\.\.\., place=free_places") as err:
        draw(suite, 0, 0, PATH)
    assert "\n" not in str(err.value)


def test_variations_with_fixtures_round_trip_and_old_records_read_back(teacher):
    _, path, place = teacher
    suite = Suite.default().replace(shelf_share=1.0, plate_share=1.0, nullspace_push=False)
    v = draw(suite, 1, 4, path, place)
    assert isinstance(v.shelf, Fixture) and isinstance(v.plate, Fixture)
    record = json.loads(json.dumps(v.to_json()))
    assert record["shelf"] == {"shape": "box", "pos": list(v.shelf.pos), "size": list(SHELF_SIZE)}
    assert Variation.from_json(record) == v
    assert v.plan.nullspace_push is False
    old = {k: x for k, x in record.items()
           if k not in ("nullspace_push", "shelf", "shelf_gap", "plate", "plate_gap")}
    back = Variation.from_json(old)
    assert (back.shelf, back.plate, back.plan.nullspace_push) == (None, None, True)
    assert back.scene(POUR).obstacles == ((v.obstacle,) if v.obstacle else ())


@pytest.mark.parametrize("text, expected", [("true", True), ("false", False)])
def test_nullspace_push_is_a_switch(tmp_path, text, expected):
    path = tmp_path / "suite.toml"
    path.write_text(f"nullspace_push = {text}\n")
    suite = load_suite(path)
    assert suite["nullspace_push"] is expected
    assert draw(suite, 0, 0, PATH).plan.nullspace_push is expected


@pytest.mark.parametrize("text", ['"yes"', "1", "0", "[true]"])
def test_nullspace_push_refuses_anything_but_true_or_false(tmp_path, text):
    path = tmp_path / "suite.toml"
    path.write_text(f"nullspace_push = {text}\n")
    with pytest.raises(ImitateError, match=r"entry nullspace_push=.* not accepted: true or "
                       r"false$") as err:
        load_suite(path)
    assert "\n" not in str(err.value)


def test_shipped_shelf_chest_and_limits_suites():
    _, shelf = named_suite("shelf", POUR)
    assert (shelf["shelf_share"], shelf["plate_share"], shelf["obstacle_share"]) == (1, 0, 0)
    assert shelf["shelf_gap"] == (0.02, 0.10) and shelf["replays"] == 1
    assert shelf["nullspace_push"] and shelf["collision_weight"] == PlanConfig.collision_weight
    _, chest = named_suite("chest", POUR)
    assert not chest["nullspace_push"] and chest["obstacle_share"] == 0 and chest["replays"] == 1
    assert chest["shelf_share"] == chest["plate_share"] == chest["limit_margin"] == 0
    _, limits = named_suite("limits", POUR)
    assert limits["limit_margin"] == 0.13 and limits["nullspace_push"]
    assert limits["obstacle_share"] == 0 and limits["replays"] == 1


def test_limit_margin_narrows_the_planned_ranges_but_never_past_the_rest_pose():
    full = planning_task().kin
    v = draw(named_suite("limits", POUR)[1], 0, 0, PATH)
    m = v.limit_margin
    narrowed = v.planning_task(POUR, None).kin
    rest = humanoid.rest_pose()
    np.testing.assert_allclose(narrowed.lower, np.minimum(full.lower + m, rest))
    np.testing.assert_allclose(narrowed.upper, np.maximum(full.upper - m, rest))
    assert np.all(narrowed.lower <= rest) and np.all(rest <= narrowed.upper)
    stopped = planning_task(limit_margin=0.15).kin  # torso_pitch: 0.15 rad would pass its rest
    stops = np.flatnonzero(stopped.lower == rest)
    assert [full.joints[j] for j in stops] == ["torso_pitch"]
    np.testing.assert_array_equal(narrowed.span, full.span)  # the joint metric: full ranges
    with pytest.raises(ImitateError, match=r"^limit_margin=0\.5 not accepted: it leaves joint "
                       r"'torso_pitch' 0\.000 rad of its .* give a smaller margin$"):
        planning_task(limit_margin=0.5)
    zero = Variation.from_json({**v.to_json(), "limit_margin": 0.0}).planning_task(POUR, None).kin
    assert np.array_equal(zero.lower, full.lower) and np.array_equal(zero.upper, full.upper)
    for bad in (-0.1, float("nan"), True, "0.1"):
        with pytest.raises(ImitateError, match=r"^limit_margin=.* not accepted: a finite angle "
                           r">= 0 \[rad\]; 0 keeps the joints' full ranges$"):
            planning_task(limit_margin=bad)
