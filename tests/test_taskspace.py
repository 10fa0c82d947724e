"""Task space (eq. 1): its columns, the gaze frames, the demonstration map's values, unwrapping
and angle convention, and the robot map ``TaskMap`` (value, Jacobian, rates) against
``task_space`` and finite differences on a toy MuJoCo model."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.motion.kinematics import Kinematics
from imitate.motion.taskspace import TaskMap
from imitate.taskspace import (
    EQ1,
    Angles,
    Relative,
    TaskSpace,
    gaze_frame,
    gaze_of_camera,
    image_angle,
    object_orientation,
    own_frame,
)

ANGLES = EQ1.angles
N_LINKS = 3  # hinges per object chain
# A space with a place (a body fixed to the world): the target relative to it, the tool relative
# to the target, the tool's angles only.
PLACED = TaskSpace((Relative("target", "spot"), Relative("tool", "target"), Angles("tool")))
# Positions in the objects' own frames: the tool relative to the target in the target's and in
# its own, the target relative to the place in the tool's, beside the target's angles.
FRAMED = TaskSpace((Relative("tool", "target", "target"), Relative("tool", "target", "tool"),
                    Relative("target", "spot", "tool"), Angles("target")))


def task_space(p_tool, a_tool, p_target, a_target, gaze, **kwargs):
    """Eq. 1 of the two objects' trajectories."""
    return EQ1({"tool": (p_tool, a_tool), "target": (p_target, a_target)}, gaze, **kwargs)
H = 1e-6  # central-difference step [rad]


def _fmt(values) -> str:
    return " ".join(f"{v:.17g}" for v in values)


def _toy_kinematics(seed: int) -> Kinematics:
    """Two serial chains of hinges with random axes and offsets, ending in a ``tool`` and a
    ``target`` body with random orientations (a toy robot holding two objects)."""
    rng = np.random.default_rng(seed)
    chains, joints = [], []
    for name in ("tool", "target"):
        xml = close = ""
        for i in range(N_LINKS):
            joints.append(f"{name}{i}")
            xml += (
                f'<body name="{name}_link{i}" pos="{_fmt(rng.normal(scale=0.2, size=3))}">'
                f'<joint name="{name}{i}" type="hinge" axis="{_fmt(rng.normal(size=3))}"/>'
                '<geom type="sphere" size="0.02"/>'
            )
            close += "</body>"
        quat = Rotation.random(random_state=rng).as_quat(scalar_first=True)
        xml += (
            f'<body name="{name}" pos="{_fmt(rng.normal(scale=0.2, size=3))}" quat="{_fmt(quat)}">'
            '<geom type="cylinder" size="0.03 0.1"/></body>'
        )
        chains.append(xml + close)
    spot = f'<body name="spot" pos="{_fmt(rng.normal(scale=0.3, size=3))}"/>'
    model = mujoco.MjModel.from_xml_string(
        f"<mujoco><worldbody>{''.join(chains)}{spot}</worldbody></mujoco>"
    )
    return Kinematics(model, joints)


def _toy(
    seed: int, gaze: np.ndarray | None = None, fixed=(), space: TaskSpace = EQ1
) -> tuple[TaskMap, np.ndarray]:
    kin = _toy_kinematics(seed)
    gaze = Rotation.random(random_state=seed).as_matrix() if gaze is None else gaze
    q = np.random.default_rng(seed + 50).uniform(-np.pi, np.pi, kin.n)
    return TaskMap(kin, "tool", "target", gaze, fixed, space), q


def _at(task: TaskMap, q: np.ndarray, ref) -> tuple[np.ndarray, np.ndarray]:
    task.kin.update(q)
    return task(np.asarray(ref, dtype=float))


def _axis(task: TaskMap, body: str) -> np.ndarray:
    return task.kin.data.body(body).xmat.reshape(3, 3)[:, 2].copy()


def _fd_jacobian(task: TaskMap, q: np.ndarray, ref: np.ndarray) -> np.ndarray:
    cols = []
    for e in np.eye(len(q)) * H:
        cols.append((_at(task, q + e, ref)[0] - _at(task, q - e, ref)[0]) / (2 * H))
    return np.array(cols).T


def _frame_task_space(task: TaskMap) -> np.ndarray:
    """The task's space of the tool's and target's frames (origin, z axis) and the places'
    bodies, read from MuJoCo."""
    d = task.kin.data
    tracks = {role: (d.body(role).xpos[None], _axis(task, role)[None])
              for role in ("tool", "target")}
    tracks.update({name: (d.body(name).xpos[None], None) for name in task.space.places})
    return task.space(tracks, task.gaze)[0]


@pytest.mark.parametrize(("seed", "space"), [(0, EQ1), (1, EQ1), (2, EQ1), (3, EQ1),
                                             (4, PLACED), (5, PLACED), (6, FRAMED), (7, FRAMED),
                                             (8, FRAMED)])
def test_task_map_value_jacobian_rates_and_curvature_match_the_space_and_finite_differences(
    seed, space
):
    task, q = _toy(seed, space=space)
    kin = task.kin
    kin.update(q)
    expected = _frame_task_space(task)
    ref = space.angle_ref(expected)
    x, J, frame = task.evaluate(ref)
    assert x.shape == (space.m,)
    np.testing.assert_allclose(x, expected, atol=1e-12)  # the robot map is the demos' map
    np.testing.assert_allclose(J, _fd_jacobian(task, q, ref), atol=1e-6)
    rng = np.random.default_rng(seed)
    directions = rng.normal(size=(2, kin.n))
    kin.update(q)
    rates = task.rates(directions, frame)
    for b, rate in zip(directions, rates, strict=True):
        jp = _at(task, q + H * b, ref)[1]
        jm = _at(task, q - H * b, ref)[1]
        np.testing.assert_allclose(rate, (jp - jm) / (2 * H), atol=1e-6)
    a, c = rng.normal(size=(2, space.m))
    kin.update(q)
    np.testing.assert_allclose(task.curvature(a, directions[0], c, directions[1], frame),
                               a @ rates[0] + c @ rates[1], atol=1e-9)


def test_a_place_must_be_a_body_fixed_to_the_world():
    kin = _toy_kinematics(0)
    for place, message in (("nowhere", "no body"), ("tool_link1", "fixed to the world")):
        space = TaskSpace((Relative("tool", place), Angles("tool")))
        with pytest.raises(ImitateError, match=message):
            TaskMap(kin, "tool", "target", np.eye(3), space=space)


def test_a_space_is_declared_from_its_terms():
    assert (EQ1.m, EQ1.units, EQ1.places) == (7, ("m", "m", "m", "rad", "1", "rad", "1"), ())
    np.testing.assert_allclose(EQ1.tolerance, [0.01] * 3 + [np.radians(2.0), 0.05] * 2)
    assert PLACED.m == 8 and PLACED.places == ("spot",) and PLACED.angles.tolist() == [6]
    assert PLACED.labels({"tool": "bottle", "target": "glass"}) == (
        "glass_spot_dx", "glass_spot_dy", "glass_spot_dz", "bottle_glass_dx", "bottle_glass_dy",
        "bottle_glass_dz", "bottle_angle", "bottle_gaze")
    x = np.arange(16.0).reshape(2, 8)
    np.testing.assert_array_equal(PLACED.angle_ref(x), [[6.0, 0.0], [14.0, 0.0]])
    np.testing.assert_allclose(PLACED.distance(x), np.linalg.norm(x[:, 3:6], axis=1))
    for terms, message in (((), "needs terms"), ((Angles("tool"),), "needs a Relative"),
                           ((Relative("tool", "tool"),), "two names"),
                           ((Relative("tool", "spot"), Angles("spot")), "held objects"),
                           ((Relative("tool", "spot"), Angles("tool"), Angles("tool")), "once")):
        with pytest.raises(ImitateError, match=message):
            TaskSpace(terms)
    assert FRAMED.text[:2] == ("tool-target@target", "tool-target@tool")
    assert TaskSpace.from_text(FRAMED.text) == FRAMED
    assert FRAMED.labels({"tool": "bottle", "target": "glass"})[:4] == (
        "bottle_glass_dx_in_glass", "bottle_glass_dy_in_glass", "bottle_glass_dz_in_glass",
        "bottle_glass_dx_in_bottle")
    with pytest.raises(ImitateError, match="frame is a held object"):
        TaskSpace((Relative("tool", "spot", "spot"), Angles("tool")))
    p, a = np.zeros((2, 3)), np.tile([0.0, 0.0, 1.0], (2, 1))
    with pytest.raises(ImitateError, match=r"no track of \['spot'\]"):
        PLACED({"tool": (p, a), "target": (p, a)}, np.eye(3))
    x = PLACED({"tool": (p + 1.0, a), "target": (p, a), "spot": (p - 2.0, None)}, np.eye(3))
    np.testing.assert_allclose(x[:, :6], [[2.0, 2.0, 2.0, 1.0, 1.0, 1.0]] * 2)


def test_an_objects_own_frame_turns_with_its_axis_and_the_gaze():
    """``z`` the axis, ``x`` the gaze's forward made perpendicular to it, ``y = z x x``; the
    camera's right in forward's place where the axis lies along the gaze; the robot map agrees
    there too."""
    gaze = gaze_frame((1.0, 0.2, -0.3))
    right, down, forward = gaze.T
    frame = own_frame([0.0, 0.0, 2.0], gaze)  # upright, any length
    horizontal = forward * [1.0, 1.0, 0.0] / np.linalg.norm(forward[:2])
    np.testing.assert_allclose(frame, [horizontal, np.cross([0, 0, 1], horizontal), [0, 0, 1]],
                               atol=1e-12)
    np.testing.assert_allclose(own_frame(forward, gaze), [right, down, forward], atol=1e-12)
    task, q = _toy(9, space=FRAMED)
    task.kin.update(q)
    task, _ = _toy(9, gaze_frame(_axis(task, "tool"), up=(0.3, 0.1, 1.0)), space=FRAMED)
    task.kin.update(q)
    x, J = task(np.zeros(2))
    np.testing.assert_allclose(x, _frame_task_space(task), atol=1e-12)
    assert np.all(np.isfinite(J))


@pytest.mark.parametrize("side", [-1.0, 1.0])
def test_task_map_jacobian_and_branch_at_the_angle_wrap(side):
    task, q = _toy(11)
    task.kin.update(q)
    a = _axis(task, "tool")
    rng = np.random.default_rng(11)
    forward = np.cross(a, rng.normal(size=3))
    forward /= np.linalg.norm(forward)
    # Camera right against the axis, turned by 1e-7 rad about forward: angle ~ +-(pi - 1e-7).
    right = Rotation.from_rotvec(forward * side * 1e-7).as_matrix() @ -a
    task, _ = _toy(11, np.column_stack((right, np.cross(forward, right), forward)))
    x, J = _at(task, q, [np.pi, 0.0])
    assert abs(abs(x[3]) - np.pi) < 1e-6
    np.testing.assert_allclose(J, _fd_jacobian(task, q, x[ANGLES]), atol=1e-6)


def test_task_map_picks_the_branch_nearest_to_angle_ref():
    task, q = _toy(5)
    x, _ = _at(task, q, [0.0, 0.0])
    assert -np.pi <= x[3] <= np.pi and -np.pi <= x[5] <= np.pi
    for k in (-2, 1, 3):
        for offset in (-np.pi + 0.01, 0.4, np.pi - 0.01):
            xk, _ = _at(task, q, x[ANGLES] + 2 * np.pi * k + offset)
            np.testing.assert_allclose(xk[ANGLES], x[ANGLES] + 2 * np.pi * k, atol=1e-12)
            np.testing.assert_array_equal(np.delete(xk, ANGLES), np.delete(x, ANGLES))


def test_task_map_holds_angle_ref_with_a_zero_row_when_the_axis_is_along_the_gaze():
    task, q = _toy(3)
    task.kin.update(q)
    a = _axis(task, "tool")
    gaze = gaze_frame(a, up=np.random.default_rng(3).normal(size=3))  # along the tool's axis
    task, _ = _toy(3, gaze)
    task.kin.update(q)
    x, J, frame = task.evaluate(np.array([0.7, 0.0]))
    assert x[3] == 0.7
    np.testing.assert_array_equal(J[3], 0.0)
    np.testing.assert_allclose(x[4], 1.0)
    assert np.all(np.isfinite(J)) and np.any(J[4] != 0.0)  # a . f keeps its gradient
    rates = task.rates(np.ones((1, task.kin.n)), frame)
    assert np.all(np.isfinite(rates))
    np.testing.assert_array_equal(rates[0, 3], 0.0)


def test_task_map_fixed_joints_and_bad_gaze():
    task, q = _toy(2, fixed=("tool1", "target0"))
    _, J = _at(task, q, [0.0, 0.0])
    np.testing.assert_array_equal(J[:, [1, N_LINKS]], 0.0)
    assert np.all(np.any(J[:, task.driven] != 0.0, axis=0))
    kin = task.kin
    with pytest.raises(ImitateError, match="unknown"):
        TaskMap(kin, "tool", "target", np.eye(3), ("elbow",))
    with pytest.raises(ImitateError, match="right-handed"):
        TaskMap(kin, "tool", "target", np.diag([1.0, -1.0, 1.0]))


def test_gaze_frame_is_right_down_forward():
    gaze = gaze_frame([0.0, 2.0, 0.0])  # looking along +y: right = +x, down = -z
    np.testing.assert_allclose(gaze, [[1, 0, 0], [0, 0, 1], [0, -1, 0]], atol=1e-15)
    assert np.linalg.det(gaze) == pytest.approx(1.0)
    for seed in range(5):
        forward = np.random.default_rng(seed).normal(size=3)
        g = gaze_frame(forward)
        np.testing.assert_allclose(g.T @ g, np.eye(3), atol=1e-12)
        np.testing.assert_allclose(np.cross(g[:, 0], g[:, 1]), g[:, 2], atol=1e-12)
        np.testing.assert_allclose(g[:, 2], forward / np.linalg.norm(forward))
        assert g[2, 0] == pytest.approx(0.0, abs=1e-12) and g[2, 1] < 0  # level, down is down


def test_angle_convention_upright_is_minus_half_pi_and_clockwise_in_the_image():
    gaze = gaze_frame([0.6, 0.8, -0.3])  # a level camera looking somewhat down
    tilt = np.linspace(0.0, 1.5, 7)  # upright, then the top towards the image's right
    axes = np.outer(np.cos(tilt), [0.0, 0.0, 1.0]) + np.outer(np.sin(tilt), gaze[:, 0])
    angle, _, defined = object_orientation(axes, gaze)
    assert defined.all()
    assert angle[0] == pytest.approx(-np.pi / 2)
    assert np.all(np.diff(angle) > 0) and angle[-1] < 0 and angle[-1] > -0.2
    # A pinhole camera with OpenCV axes (rows of R = the gaze columns): the axis's image on the
    # optical axis points at atan2(d row, d col), rows growing down: clockwise from "right".
    centre = np.array([0.2, -0.1, 1.0])
    K = np.array([[500.0, 0.0, 320.0], [0.0, 500.0, 240.0], [0.0, 0.0, 1.0]])

    def pixel(p):
        cam = K @ (gaze.T @ (p - centre))
        return cam[:2] / cam[2]

    for a, phi in zip(axes, angle, strict=True):
        du, dv = pixel(centre + gaze[:, 2] + 0.01 * a) - pixel(centre + gaze[:, 2])
        assert np.arctan2(dv, du) == pytest.approx(phi, abs=1e-12)


def test_task_space_values_and_unwrapping():
    gaze = gaze_frame([1.0, 0.0, 0.0])  # right = -y, down = -z
    n = 200
    turn = np.linspace(0.0, 3 * 2 * np.pi, n)  # three full turns from right towards down
    a_b = np.column_stack((np.full(n, 0.3), -np.cos(turn), -np.sin(turn)))
    a_g = np.tile([0.0, 0.0, 1.0], (n, 1))
    p_b = np.column_stack((np.linspace(0, 1, n), np.zeros(n), np.ones(n)))
    p_g = np.zeros((n, 3))
    x = task_space(p_b, a_b, p_g, a_g, gaze)
    np.testing.assert_allclose(x[:, 3], turn, atol=1e-12)
    np.testing.assert_allclose(x[:, :3], p_b - p_g)
    np.testing.assert_allclose(x[:, 4], 0.3 / np.linalg.norm(a_b, axis=1))
    np.testing.assert_allclose(x[:, 5], -np.pi / 2)
    np.testing.assert_allclose(x[:, 6], 0.0, atol=1e-15)


def test_task_space_holds_angle_through_singular_samples():
    gaze = gaze_frame([1.0, 0.0, 0.0])
    a = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
    a_start = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    p = np.zeros((4, 3))
    x = task_space(p, a, p, a, gaze)
    np.testing.assert_allclose(x[:3, 3], -np.pi / 2)
    np.testing.assert_allclose(x[3, 3], 0.0)
    x2 = task_space(p[:2], a_start, p[:2], a_start, gaze)
    np.testing.assert_allclose(x2[:, 3], -np.pi / 2)  # leading undefined sample takes the next


def test_object_orientation_defined_flag_and_gaze_component():
    gaze = gaze_frame([0.0, 1.0, 0.0])
    angle, along, defined = object_orientation([[1, 0, 0], [0, 0, 2], [0, 1, 0]], gaze)
    np.testing.assert_allclose(angle[:2], [0.0, -np.pi / 2])
    np.testing.assert_allclose(along, [0.0, 0.0, 1.0], atol=1e-15)
    assert defined.tolist() == [True, True, False]


def test_bad_input_is_rejected():
    p = np.zeros((3, 3))
    a = np.tile([0.0, 0.0, 1.0], (3, 1))
    gaze = np.eye(3)
    with pytest.raises(ImitateError, match="orthonormal"):
        task_space(p, a, p, a, np.diag([1.0, 2.0, 1.0]))
    with pytest.raises(ImitateError, match="right-handed"):
        task_space(p, a, p, a, np.diag([1.0, 1.0, -1.0]))  # right, up, forward
    with pytest.raises(ImitateError, match=r"target positions must have shape \(3, 3\)"):
        task_space(p, a, p[:2], a, gaze)
    with pytest.raises(ImitateError, match="finite"):
        task_space(np.full((3, 3), np.nan), a, p, a, gaze)
    with pytest.raises(ImitateError, match="non-zero"):
        task_space(p, np.zeros((3, 3)), p, a, gaze)
    with pytest.raises(ImitateError, match="parallel"):
        gaze_frame([0.0, 0.0, 2.0])


def test_columns_name_the_position_and_the_angles():
    dims, units = EQ1.labels(), EQ1.units
    assert len(dims) == len(units) == EQ1.m == 7
    assert dims[EQ1.positions[0]] == ("dx", "dy", "dz")
    assert [dims[i] for i in ANGLES] == ["tool_angle", "target_angle"]
    assert [units[i] for i in ANGLES] == ["rad", "rad"]
    assert [dims[i + 1] for i in ANGLES] == ["tool_gaze", "target_gaze"]
    # Pouring prints its own words for the columns: the bottle is the tool, the glass the target.
    renamed = tuple(d.replace("tool", "bottle").replace("target", "glass") for d in dims)
    assert get_task("pour").dims == renamed
    with pytest.raises(ValueError, match="read-only"):
        ANGLES[0] = 4


def test_gaze_of_a_pinhole_camera_and_of_a_mujoco_camera():
    rotation = Rotation.random(random_state=7).as_matrix()  # a MuJoCo camera: right, up, backward
    gaze = gaze_of_camera(rotation, mujoco=True)
    np.testing.assert_array_equal(gaze, np.column_stack((rotation[:, 0], -rotation[:, 1],
                                                         -rotation[:, 2])))
    assert np.linalg.det(gaze) == pytest.approx(1.0)
    # OpenCV's world-to-camera rotation has the gaze columns as its rows.
    np.testing.assert_array_equal(gaze_of_camera(gaze.T), gaze)
    # A pinhole camera with that rotation sees a point below its gaze lower in the image and a
    # point to its right further right.
    centre, K = np.array([0.3, -0.2, 1.1]), np.diag([500.0, 500.0, 1.0])

    def pixel(p):
        cam = K @ (gaze.T @ (p - centre))
        return cam[:2] / cam[2]

    ahead = centre + gaze[:, 2]
    assert pixel(ahead + 0.1 * gaze[:, 1])[1] > pixel(ahead)[1]
    assert pixel(ahead + 0.1 * gaze[:, 0])[0] > pixel(ahead)[0]
    with pytest.raises(ImitateError, match="right-handed"):
        gaze_of_camera(np.diag([1.0, 1.0, -1.0]))  # rows right, up, forward: left-handed


def test_image_angle_is_object_orientations_angle_for_any_length_and_missing_axes():
    gaze = gaze_frame([0.6, 0.8, -0.3])
    axes = np.random.default_rng(4).normal(size=(2, 5, 3))
    angle, _, _ = object_orientation(axes, gaze)
    np.testing.assert_allclose(image_angle(axes, gaze), angle, atol=1e-15)
    np.testing.assert_allclose(image_angle(3.0 * axes, gaze), angle, atol=1e-15)
    axes[1, 2] = np.nan  # an object not seen in one frame
    seen = image_angle(axes, gaze)
    assert np.isnan(seen[1, 2]) and np.isfinite(np.delete(seen.ravel(), 7)).all()
    with pytest.raises(ImitateError, match="orthonormal"):
        image_angle(axes, np.diag([1.0, 2.0, 1.0]))


def test_the_contract_loads_neither_the_planner_nor_mujoco():
    import subprocess
    import sys

    code = ("import sys, imitate.taskspace\n"
            "print(sorted(m for m in ('numba', 'mujoco', 'scipy') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True)
    assert done.stdout.strip() == "[]"


def test_a_place_stands_on_the_table_and_the_robot_maps_a_space_relative_to_it():
    """A marker placed in the pouring scene: fixed where it was put, an obstacle to the planner,
    refused off the table, too near the robot or missing from a space that names it; the
    robot's map of the glass relative to it matches finite differences."""
    import dataclasses

    from imitate.envs.assembly import Place, build_model, check_clearance
    from imitate.models import humanoid
    from imitate.motion.replay import planning_task

    space = TaskSpace((Relative("tool", "target"), Relative("target", "marker"), Angles("tool"),
                       Angles("target")))
    scene = dataclasses.replace(get_task("pour").scene(), places=(Place("marker", 0.6, 0.1),),
                                space=space)
    model = build_model(scene)
    marker = model.body("marker")
    assert model.body_weldid[marker.id] == 0 and marker.pos[2] == pytest.approx(0.61)
    task_map = planning_task(scene)
    pairs = task_map.kin.pairs
    assert any("marker_hull_0" in pairs.names(task_map.kin.model, i) for i in range(len(pairs)))
    q = humanoid.rest_pose() + np.random.default_rng(0).uniform(-0.1, 0.1, task_map.kin.n)
    task_map.kin.update(q)
    glass = task_map.kin.data.body("glass").xpos
    x, J = task_map(np.zeros(2))
    np.testing.assert_allclose(x[3:6], glass - (0.6, 0.1, 0.61), atol=1e-12)
    fd = _fd_jacobian(task_map, q, space.angle_ref(x))
    np.testing.assert_allclose(J, fd, atol=1e-6)
    with pytest.raises(ImitateError, match="within the table top"):
        Place("marker", 1.3, 0.0)
    with pytest.raises(ImitateError, match="clear of the robot"):
        check_clearance(dataclasses.replace(scene, places=(Place("marker", 0.42, -0.18),)), 0.05)
    with pytest.raises(ImitateError, match=r"relative to \['marker'\], not in places"):
        dataclasses.replace(scene, places=())


def test_a_space_is_stored_as_text_and_read_back():
    assert EQ1.text == ("tool-target", "tool angles", "target angles")
    assert TaskSpace.from_text(PLACED.text) == PLACED
    with pytest.raises(ImitateError, match=r"term 'tool target' not accepted: 'OF-TO', "):
        TaskSpace.from_text(["tool target"])
    assert EQ1.columns(Angles("tool")) == slice(3, 5)
    assert PLACED.columns(Relative("tool", "target")) == slice(3, 6)
    with pytest.raises(ImitateError, match="is not a term of the task space"):
        EQ1.columns(Relative("target", "spot"))
