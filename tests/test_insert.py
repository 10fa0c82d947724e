"""The insertion task: its env's contract, its measure and outcome, its teacher's script in
physics, the clearance with the stick in the glass, and the robot's eyes seeing the stick."""

from __future__ import annotations

import dataclasses
import json

import cv2
import gymnasium as gym
import mujoco
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import imitate  # noqa: F401  (registers the envs)
from imitate.envs import assembly
from imitate.envs.collision import CollisionPairs, signed_distances
from imitate.envs.insert.env import InsertingEnv
from imitate.envs.insert.geometry import stick_end
from imitate.envs.insert.outcome import OUTCOMES, SUCCESS_DEPTH, outcome
from imitate.envs.insert.task import insert_phase
from imitate.envs.insert.teacher import DEPTH, SCRIPT, teacher_insert
from imitate.envs.task import get_task
from imitate.envs.teacher_motion import TeacherConfig, script_demonstrations
from imitate.models import humanoid, objects
from imitate.perception.colour import object_models
from imitate.taskspace import EQ1

SMALL = {"width": 96, "height": 72}
GLASS_HEIGHT = objects.GLASS_SHAPE.height


def test_check_env_of_the_registered_id():
    env = gym.make("imitate/Inserting-v0", render_mode="rgb_array", **SMALL)
    check_env(env.unwrapped, skip_render_check=False)
    obs, info = env.reset(seed=0)
    assert obs.shape == (50,) and info["insert_depth"] == 0.0 and not info["is_success"]
    for _ in range(3):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
    assert not terminated and not truncated and {"reward_insert", "reward_collision"} <= set(info)
    env.close()


def test_the_env_holds_the_glass_where_the_task_does():
    env = InsertingEnv()
    env.reset(seed=0)
    assert env.config.contact == "inside" and env.config.objects == (objects.STICK, objects.GLASS)
    assert env.config.grasps == tuple(get_task("insert").reset_options().values())
    env.close()


def _scene(contact: str = "inside") -> tuple[mujoco.MjModel, mujoco.MjData]:
    """The robot at rest holding nothing (welds off), the stick and the glass free."""
    config = assembly.SceneConfig(
        teacher=False, objects=(objects.STICK, objects.GLASS), grasps=(0.17, 0.03),
        contact=contact,
    )
    model = assembly.build_model(config)
    data = mujoco.MjData(model)
    data.qpos[[model.joint(j).qposadr[0] for j in humanoid.JOINTS]] = humanoid.rest_pose()
    data.eq_active[:] = False
    return model, data


def _place(model, data, stick_bottom, glass_bottom=(0.6, 0.0, 1.0), tilt=0.0) -> None:
    """The glass upright at ``glass_bottom``, the stick's lower end at ``stick_bottom`` (tilted
    by ``tilt`` [rad] about x)."""
    for name, pos, quat in (
        (objects.GLASS, glass_bottom, (1.0, 0.0, 0.0, 0.0)),
        (objects.STICK, stick_bottom, (np.cos(tilt / 2), np.sin(tilt / 2), 0.0, 0.0)),
    ):
        adr = model.joint(name).qposadr[0]
        data.qpos[adr : adr + 7] = (*pos, *quat)
    mujoco.mj_kinematics(model, data)


@pytest.mark.parametrize(
    ("bottom", "inside"),
    [
        ((0.6, 0.0, 1.06), 0.04),  # 40 mm below the rim, on the axis
        ((0.6, 0.02, 1.08), 0.02),  # 20 mm below it, 20 mm off the axis
        ((0.6, 0.0, 1.12), 0.0),  # above the rim
        ((0.6, 0.09, 1.06), 0.0),  # below the rim, beside the glass
    ],
)
def test_the_lower_end_counts_inside_the_glass_only(bottom, inside):
    model, data = _scene()
    _place(model, data, bottom)
    depth, offset, inside_depth, tilt = stick_end(data)
    assert depth == pytest.approx(1.0 + GLASS_HEIGHT - bottom[2])
    assert offset == pytest.approx(np.hypot(bottom[0] - 0.6, bottom[1]))
    assert inside_depth == pytest.approx(inside) and tilt == pytest.approx(0.0, abs=1e-6)


def test_the_lower_end_is_the_lower_of_the_two():
    model, data = _scene()
    top = 1.06 + objects.STICK_SHAPE.height  # upside down: its top goes in, 40 mm deep
    _place(model, data, (0.6, 0.0, top), tilt=np.pi)
    depth, _, inside, tilt = stick_end(data)
    assert depth == pytest.approx(0.04) and inside == pytest.approx(0.04)
    assert tilt == pytest.approx(180.0)


def _clearance(contact: str, stick_bottom) -> tuple[float, set[tuple[str, str]]]:
    """The smallest signed distance [m] over the clearance pairs, and the pairs' geom names, of
    the stick with its lower end at ``stick_bottom``, the glass at ``(0.6, 0, 1)``."""
    model, data = _scene(contact)
    _place(model, data, stick_bottom)
    pairs = CollisionPairs.between(model, assembly.clearance_geoms(model))
    names = {pairs.names(model, k) for k in range(len(pairs))}
    return float(signed_distances(model, data, pairs)[0].min()), names


def test_the_stick_keeps_clear_of_the_glass_s_walls_not_of_its_hull():
    """Inside the glass the stick's hull overlaps the glass's solid hull: the insertion's
    clearance measures the stick against the glass's walls and floor instead (and nothing else
    against them); through the wall is a collision still."""
    centred, names = _clearance("inside", (0.6, 0.0, 1.045))
    through, _ = _clearance("inside", (0.6, 0.04, 1.07))
    solid, solid_names = _clearance("apart", (0.6, 0.0, 1.045))
    glass = {pair for pair in names if any(n.startswith("glass_") for n in pair)}
    walls = {pair for pair in glass if "glass_hull_0" not in pair}
    assert walls and all(sorted(pair)[1] == "stick_hull_0" for pair in walls)
    assert {"glass_floor", *(f"glass_wall_{k}" for k in range(18))} == {
        n for pair in walls for n in pair if n != "stick_hull_0"
    }
    assert ("stick_hull_0", "glass_hull_0") not in names | {p[::-1] for p in names}
    assert solid_names - names == {("stick_hull_0", "glass_hull_0")}
    assert 0.005 < centred and through < 0 and solid < -0.01


def test_pouring_keeps_its_bottle_glass_pair():
    pour = assembly.build_model(assembly.SceneConfig(teacher=False))
    pairs = CollisionPairs.between(pour, assembly.clearance_geoms(pour))
    names = {pairs.names(pour, k) for k in range(len(pairs))}
    assert ("bottle_hull_0", "glass_hull_0") in names | {p[::-1] for p in names}
    assert not any("wall" in a + b or "floor" in a + b for a, b in names)


def test_the_planner_sees_the_glass_s_walls():
    planner = assembly.planning_model(get_task("insert").scene())
    pairs = CollisionPairs.between(planner, assembly.clearance_geoms(planner))
    names = {pairs.names(planner, k) for k in range(len(pairs))}
    assert sum("glass_wall" in a + b for a, b in names) == 18


def _replay(depth: float, *, distance: float = 0.01, diverged: bool = False) -> dict:
    return {"insert_depth": depth, "insert_offset": 0.005, "min_distance_m": distance,
            "diverged": diverged}


@pytest.mark.parametrize(
    ("plan", "replays", "expected"),
    [
        (0.01, [_replay(0.04)] * 3, "success"),
        (0.01, [_replay(0.04), _replay(SUCCESS_DEPTH), _replay(0.05)], "success"),
        (0.01, [_replay(0.04), _replay(0.02), _replay(0.05)], "shallow"),
        (0.01, [_replay(0.04), _replay(0.0), _replay(0.05)], "missed"),
        (0.01, [_replay(0.04), _replay(0.04, distance=-0.001), _replay(0.04)], "physics_contact"),
        (-0.002, [_replay(0.04)] * 3, "plan_collision"),
        (-0.002, [_replay(0.04), _replay(0.0, diverged=True), _replay(0.04)], "diverged"),
    ],
)
def test_outcome_takes_the_worst_replay(plan, replays, expected):
    assert expected in OUTCOMES
    assert outcome(plan, replays, get_task("insert").settings()) == expected


def test_the_insert_phase_is_where_the_mean_holds_the_stick_in_the_glass():
    mean = np.zeros((100, 7))
    mean[:, 1] = np.where(np.arange(100) < 40, -0.2, 0.0)  # beside, then over the glass
    mean[:, 2] = np.linspace(0.3, 0.05, 100)  # down, to 5 cm above the glass's bottom
    phase = insert_phase(mean, EQ1)
    assert phase.any() and np.all(mean[phase, 2] <= GLASS_HEIGHT + 0.01)
    assert not phase[:40].any() and phase[-1]
    beside = mean.copy()
    beside[:, 1] = -0.2 + np.linspace(0.0, 0.1, 100)  # never over the opening
    assert np.flatnonzero(insert_phase(beside, EQ1)).min() >= 85  # the nearest tenth


@pytest.mark.parametrize("seed", [0, 3])
def test_the_teachers_demonstrations_put_the_stick_into_the_glass(seed):
    motion = script_demonstrations(TeacherConfig(task="insert", seed=seed, n_demos=2))
    depths = [teacher_insert(motion, demo) for demo in range(2)]
    assert all(DEPTH - 0.005 < depth < DEPTH + 0.008 for depth in depths), depths


def test_the_script_agrees_in_the_descent_and_varies_on_the_approach():
    motion = script_demonstrations(TeacherConfig(task="insert", seed=0, n_demos=8))
    first, last = SCRIPT.agree_rows
    approach = SCRIPT.swing_rows[-1]
    u = [SCRIPT.waypoints[row][0] for row in (approach, first, last)]
    ends = np.array([path(u)[:, 4:7] for path in motion.paths])  # (demos, 3 rows, top - rim)
    spread = ends.std(axis=0)
    assert spread[0, 0] > 0.03 and np.all(spread[1:] < 0.004)


def test_the_robot_sees_the_stick_and_the_glass_in_the_teachers_hands():
    from imitate.envs.observation import ObservationConfig, frames, session

    config = ObservationConfig(teacher=TeacherConfig(task="insert", seed=0, n_demos=1),
                               width=320, height=240)
    sess = session(config)
    start, end = sess.motion.boundaries[0]
    sess = dataclasses.replace(sess, times=np.array([start + 0.6 * (end - start)]))
    left, _ = next(frames(sess, ahead=False))
    hsv = cv2.cvtColor(left, cv2.COLOR_RGB2HSV)
    models = object_models(sess.motion.objects)
    assert [m.name for m in models] == [objects.STICK, objects.GLASS]
    assert all(np.count_nonzero(m.colour.mask(hsv)) > 50 for m in models)


def test_a_quick_insert_run_end_to_end_reports_its_declared_keys(tmp_path):
    """``imitate run --task insert --quick``: every stage, on rendered images; its report holds
    every key the task declares, each of its kind (as the next stage would read it), and its
    page shows the insertion's headline."""
    from imitate.cli import main
    from imitate.rundir import layout
    from imitate.rundir.schema import check_values
    from imitate.stages.runner import run_keys

    run_dir = tmp_path / "insert"
    assert main(["run", "--task", "insert", "--quick", "--out", str(run_dir)]) == 0
    report = json.loads((run_dir / layout.REPORT).read_text())
    task = get_task("insert")
    check_values(report, run_dir / layout.REPORT, *run_keys(task))
    replay = report["replay"]
    assert {key.split(".")[1] for key in task.keys if key.startswith("replay.")} <= set(replay)
    assert np.isfinite(replay["insert_depth"]) and replay["outcome"] in task.outcomes
    assert "insertion depth" in (run_dir / layout.PAGE).read_text()
