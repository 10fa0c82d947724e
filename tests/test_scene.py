"""The composed model: naming, dimensions, variants and bad scene options."""

import mujoco
import numpy as np
import pytest

from imitate.envs import assembly
from imitate.envs.collision import CollisionPairs
from imitate.envs.pour.env import PouringEnv
from imitate.envs.pour.liquid import Liquid, particle_bodies
from imitate.errors import ImitateError
from imitate.models import humanoid, objects
from imitate.models import scene as names
from imitate.models import teacher as teacher_names
from imitate.motion.replay import planning_task


@pytest.fixture(scope="module")
def model():
    return assembly.build_model(assembly.SceneConfig(contents=(Liquid(5),), obstacles=(_box(),)))


def _box(pos=(0.6, 0.2, 0.72)):
    return assembly.Obstacle("box", pos, (0.05, 0.05, 0.07))


def _data_at_rest(model):
    data = mujoco.MjData(model)
    for joint, angle in zip(humanoid.JOINTS, humanoid.rest_pose(), strict=True):
        data.qpos[model.joint(joint).qposadr[0]] = angle
    assembly.hold(model, data, "robot")
    mujoco.mj_forward(model, data)
    return data


@pytest.mark.parametrize(
    "kind, count",
    [
        (mujoco.mjtObj.mjOBJ_BODY, "nbody"),
        (mujoco.mjtObj.mjOBJ_JOINT, "njnt"),
        (mujoco.mjtObj.mjOBJ_GEOM, "ngeom"),
        (mujoco.mjtObj.mjOBJ_SITE, "nsite"),
        (mujoco.mjtObj.mjOBJ_CAMERA, "ncam"),
        (mujoco.mjtObj.mjOBJ_ACTUATOR, "nu"),
        (mujoco.mjtObj.mjOBJ_EQUALITY, "neq"),
    ],
)
def test_every_element_is_named(model, kind, count):
    unnamed = [i for i in range(getattr(model, count)) if not mujoco.mj_id2name(model, kind, i)]
    assert unnamed == [] or (kind == mujoco.mjtObj.mjOBJ_BODY and unnamed == [0])  # world


def test_cameras_are_named_as_mirrored(model):
    cameras = [model.camera(i).name for i in range(model.ncam)]
    assert sorted(cameras) == sorted(names.CAMERAS)
    head = model.body("head").id
    assert {c for c in cameras if model.cam_bodyid[model.camera(c).id] == head} == set(
        humanoid.CAMERAS
    )


def test_robot_structure(model):
    assert model.nu == len(humanoid.JOINTS) == 18
    assert [model.actuator(i).name for i in range(model.nu)] == list(humanoid.ACTUATORS)
    for joints in (humanoid.RIGHT_ARM_JOINTS, humanoid.LEFT_ARM_JOINTS):
        assert len(joints) == 7
        assert all(model.jnt_limited[model.joint(j).id] for j in joints)


def test_dimensions(model):
    data = _data_at_rest(model)
    head = data.geom("head")
    assert 1.25 < head.xpos[2] + model.geom("head").size[0] < 1.35  # robot about 1.3 m
    hair = data.geom("teacher_hair")
    assert 1.7 < hair.xpos[2] + model.geom("teacher_hair").size[2] < 1.8  # teacher about 1.75 m
    baseline = np.linalg.norm(data.cam(humanoid.LEFT_EYE).xpos - data.cam(humanoid.RIGHT_EYE).xpos)
    assert 0.06 <= baseline <= 0.12
    assert model.vis.global_.offwidth >= 640 and model.vis.global_.offheight >= 480


def test_objects_held_upright_in_the_right_hands(model):
    data = _data_at_rest(model)
    for obj, hand in ((objects.BOTTLE, "right_hand"), (objects.GLASS, "left_hand")):
        axis = data.body(obj).xmat.reshape(3, 3)[:, 2]
        assert axis[2] > 0.95
        assert np.linalg.norm(data.body(obj).xpos - data.body(hand).xpos) < 0.15
    assert data.body(objects.BOTTLE).xpos[1] < 0 < data.body(objects.GLASS).xpos[1]


def test_object_colours_distinct_from_scene():
    """Bottle and glass hues are far from each other and from every other coloured geom."""
    import colorsys

    def hue_sat(rgba):
        h, _, s = colorsys.rgb_to_hls(*rgba[:3])
        return 360 * h, s

    model = assembly.build_model(assembly.SceneConfig(contents=(Liquid(1),)))
    targets = {obj: hue_sat(shape.rgba) for obj, shape in objects.SHAPES.items()}
    for g in range(model.ngeom):
        name = model.geom(g).name
        if name.startswith((objects.BOTTLE, objects.GLASS)) or model.geom_rgba[g][3] == 0:
            continue
        hue, sat = hue_sat(model.geom_rgba[g])
        for obj, (target_hue, _) in targets.items():
            gap = min(abs(hue - target_hue), 360 - abs(hue - target_hue))
            assert sat < 0.35 or gap > 40, f"{name} has a hue close to the {obj}"


def test_variants():
    bare = assembly.build_model(assembly.SceneConfig(teacher=False))
    assert bare.nmocap == 0 and len(particle_bodies(bare)) == 0
    full = assembly.build_model(assembly.SceneConfig(
        contents=(Liquid(7),), obstacles=(_box(), _box((0.9, -0.3, 0.72)))
    ))
    assert full.nmocap == 3 * len(teacher_names.SIDES) and len(particle_bodies(full)) == 7
    assert full.geom(f"{names.OBSTACLE_PREFIX}1").size[0] == pytest.approx(0.05)


def test_weld_holds_object_at_grasp():
    model = assembly.build_model(assembly.SceneConfig(grasps=(0.12, 0.05)))
    data = _data_at_rest(model)
    grip = data.site(humanoid.RIGHT_GRIP).xpos
    bottom = data.body(objects.BOTTLE).xpos
    axis = data.body(objects.BOTTLE).xmat.reshape(3, 3)[:, 2]
    np.testing.assert_allclose(grip - bottom, 0.12 * axis, atol=1e-9)


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"contact": "on"}, r"contact='on' not accepted: one of \('apart', 'inside'\)"),
        ({"holder": "nobody"}, "holder='nobody'"),
        ({"teacher": False, "holder": "teacher"}, "needs teacher=True"),
        ({"grasps": (0.3, 0.05)}, "bottle grasp height"),
        ({"grasps": (float("nan"), 0.05)}, "bottle grasp height nan"),
        ({"grasps": (0.09, "abc")}, "glass grasp height 'abc'"),
        ({"grasps": (0.09,)}, "two heights"),
        ({"objects": ("bottle", "spoon")}, "a tool and a target of"),
        ({"teacher": None}, "teacher=None not accepted"),
    ],
)
def test_bad_scene_config(kwargs, match):
    with pytest.raises(ImitateError, match=match):
        assembly.SceneConfig(**kwargs)


@pytest.mark.parametrize(
    "shape, pos, size, match",
    [
        ("box", (2.0, 0.0, 0.75), (0.05, 0.05, 0.05), "outside the table"),
        ("box", (0.6, 0.9, 0.75), (0.05, 0.05, 0.05), "outside the table"),
        ("cylinder", (0.6, 0.0, 0.5), (0.05, 0.05), "outside the table"),
        ("sphere", (0.6, 0.0, 0.75), (0.05,), "shape 'sphere' unknown"),
        ("box", (0.6, 0.0, 0.75), (0.05, -0.05, 0.05), "positive"),
        ("box", (0.55, 0.0, float("nan")), (0.03, 0.03, 0.05), "3 finite values"),
        ("box", (0.55, 0.0, float("inf")), (0.03, 0.03, 0.05), "3 finite values"),
        ("box", (0.55, 0.0, 0.7), (float("nan"), 0.03, 0.05), "3 finite positive values"),
        ("box", (0.55, 0.0, 0.7), (0.03, float("inf"), 0.05), "3 finite positive values"),
        ("cylinder", (0.55, 0.0, float("nan")), (0.03, 0.05), "3 finite values"),
        ("box", ("a", 0.0, 0.7), (0.03, 0.03, 0.05), "3 finite values"),
        # the footprint, not only the centre, on the table top
        ("box", (0.40, -0.175, 0.75), (0.1, 0.1, 0.14), r"footprint x 0\.300\.\.0\.500"),
        ("box", (0.78, 0.0, 2.61), (2.0, 2.0, 2.0), "outside the table"),
        ("cylinder", (1.14, 0.0, 0.7), (0.05, 0.05), "outside the table"),
        # floating far above the table
        ("box", (0.78, 0.0, 100.0), (0.1, 0.1, 0.1), "at most 0.5 m above it"),
    ],
)
def test_bad_obstacle(shape, pos, size, match):
    with pytest.raises(ImitateError, match=match):
        assembly.Obstacle(shape, pos, size)


def test_obstacle_values_become_floats():
    box = assembly.Obstacle("box", [np.float32(0.6), 0, 0.72], [0.05, 0.05, 0.07])
    assert box.pos == (pytest.approx(0.6), 0.0, 0.72) and isinstance(box.size, tuple)
    assert all(type(v) is float for v in box.pos + box.size)


def test_obstacle_touching_the_robot_at_the_start_is_refused():
    on_hand = assembly.Obstacle("box", (0.45, -0.17, 0.70), (0.05, 0.05, 0.09))
    with pytest.raises(ImitateError, match="overlaps 'right_hand' by 13.8 mm at the start"):
        assembly.check_clearance(assembly.SceneConfig(obstacles=(on_hand,)))
    clear = assembly.Obstacle("box", (0.55, 0.0, 0.70), (0.03, 0.03, 0.05))  # the README's
    assembly.check_clearance(assembly.SceneConfig(obstacles=(_box(), clear)))
    lower = assembly.Obstacle("box", (0.45, -0.17, 0.675), (0.05, 0.05, 0.065))  # 6.4 mm under
    assembly.check_clearance(assembly.SceneConfig(obstacles=(lower,)))
    with pytest.raises(ImitateError, match="is 6.4 mm from 'right_hand' at the start.*11 mm"):
        assembly.check_clearance(assembly.SceneConfig(obstacles=(lower,)), clearance=0.011)


def test_held_objects_keep_clear_of_table_and_obstacles(model):
    """A held object is a free body, child of the world: its pairs with the world-fixed table
    and obstacles are checked (MuJoCo's parent filter skips the world too)."""
    pairs = CollisionPairs.between(model, assembly.clearance_geoms(model))
    found = {frozenset(pairs.names(model, i)) for i in range(len(pairs))}
    for hull in ("glass_hull_0", "bottle_hull_0"):
        for other in (names.TABLE_TOP, f"{names.OBSTACLE_PREFIX}0"):
            assert frozenset((hull, other)) in found


@pytest.mark.parametrize("obj", [objects.BOTTLE, objects.GLASS])
def test_hulls_enclose_the_collision_geoms(model, obj):
    """Every corner of the walls' boxes and every rim point of the floor lies in a hull, so the
    distance between hulls never overstates the physical clearance."""
    body = model.body(obj).id
    geoms = [g for g in range(model.ngeom) if model.geom_bodyid[g] == body]
    hulls = [g for g in geoms if "_hull_" in model.geom(g).name]
    points = []
    for g in geoms:
        if not model.geom_contype[g]:
            continue
        size, rot = model.geom_size[g], np.zeros(9)
        mujoco.mju_quat2Mat(rot, model.geom_quat[g])
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_BOX:
            local = np.array(np.meshgrid(*[[-s, s] for s in size])).reshape(3, -1).T
        else:  # the floor cylinder: points around both rims
            angle = np.linspace(0, 2 * np.pi, 36, endpoint=False)
            rim = np.column_stack((size[0] * np.cos(angle), size[0] * np.sin(angle)))
            local = np.vstack([np.column_stack((rim, np.full(36, z))) for z in (-size[1], size[1])])
        points.append(model.geom_pos[g] + local @ rot.reshape(3, 3).T)
    points = np.vstack(points)
    inside = np.zeros(len(points), dtype=bool)
    for h in hulls:  # upright cylinders in the body frame
        radius, half = model.geom_size[h][:2]
        centre = model.geom_pos[h]
        inside |= (np.hypot(*(points[:, :2] - centre[:2]).T) <= radius + 1e-9) & (
            np.abs(points[:, 2] - centre[2]) <= half + 1e-9
        )
    assert inside.all(), f"{(~inside).sum()} of {len(points)} points outside the hulls"


def test_a_fixture_may_stand_off_the_table_clear_of_the_robot():
    """Off the table, over the pour, a fixture is accepted where an obstacle is refused; in the
    robot it is refused like an obstacle, in one line."""
    shelf = ("box", (0.31, -0.28, 0.95), (0.05, 0.05, 0.05))  # over the bottle in the pour
    with pytest.raises(ImitateError, match=r"outside the table.*\(a Fixture may stand off it\)"):
        assembly.Obstacle(*shelf)
    fixture = assembly.Fixture(*shelf)
    assert isinstance(fixture, assembly.Obstacle) and fixture != assembly.Obstacle(
        "box", (0.6, 0.0, 0.7), (0.05, 0.05, 0.05)
    )
    assembly.check_clearance(assembly.SceneConfig(obstacles=(fixture,)), clearance=0.011)
    in_chest = assembly.Fixture("box", (0.05, 0.0, 0.85), (0.05, 0.05, 0.05))
    with pytest.raises(ImitateError, match=r"^fixture box at pos=\(0\.05, 0\.0, 0\.85\) size="
                       r".* overlaps 'torso_chest' by .* mm at the start") as err:
        assembly.check_clearance(assembly.SceneConfig(obstacles=(in_chest,)))
    assert "\n" not in str(err.value)
    with pytest.raises(ImitateError, match=r"below the floor: its bottom \(z - half height = "
                       r"-0\.050\) must be at or above the floor z=0; raise its z$"):
        assembly.Fixture("box", (0.3, 0.0, 0.0), (0.05, 0.05, 0.05))
    with pytest.raises(ImitateError, match="fixture shape 'sphere' unknown"):
        assembly.Fixture("sphere", (0.3, 0.0, 0.9), (0.05,))


def test_the_planner_and_the_physics_see_a_fixture():
    """A fixture 5 mm over the bottle at the start: the planner's clearance and the env's both
    measure it."""
    over_bottle = assembly.Fixture("box", (0.356, -0.18, 0.941), (0.03, 0.03, 0.02))
    task = planning_task(assembly.SceneConfig(obstacles=(over_bottle,)))
    distance, pair = task.kin.min_distance()
    assert distance == pytest.approx(0.005, abs=1e-3) and f"{names.OBSTACLE_PREFIX}0" in pair
    env = PouringEnv(particles=0, teacher=False, obstacles=(over_bottle,), reset_noise_scale=0.0)
    try:
        _, info = env.reset(seed=0)
        assert info["min_distance"] == pytest.approx(distance, abs=1e-3)
    finally:
        env.close()
