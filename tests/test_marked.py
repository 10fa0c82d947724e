"""The marked pour, a task eq. 1 cannot express: its env's contract and outcome, its teacher's
script (over the marker, pouring in physics), its own task space on the robot, the robot's
eyes tracking the marker, and a quick run end to end."""

from __future__ import annotations

import json

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import imitate  # noqa: F401  (registers the envs)
from imitate.envs.marked.outcome import OUTCOMES, OVER, outcome
from imitate.envs.marked.task import SPACE
from imitate.envs.marked.teacher import MARKER_PLACE, PLACE_SPREAD, SCRIPT
from imitate.envs.pour.teacher import teacher_pour
from imitate.envs.task import get_task
from imitate.envs.teacher_motion import TeacherConfig, script_demonstrations
from imitate.models import objects
from imitate.taskspace import EQ1

SMALL = {"width": 96, "height": 72}
TASK = get_task("marked")


def test_check_env_and_the_marker_where_the_settings_put_it():
    env = gym.make("imitate/MarkedPouring-v0", render_mode="rgb_array", marker_x=0.5,
                   marker_y=-0.05, particles=10, **SMALL)
    check_env(env.unwrapped, skip_render_check=False)
    _, info = env.reset(seed=0)
    np.testing.assert_allclose(env.unwrapped.data.body(objects.MARKER).xpos, (0.5, -0.05, 0.61))
    glass = env.unwrapped.data.body(objects.GLASS).xpos
    assert info["marker_offset"] == pytest.approx(np.hypot(glass[0] - 0.5, glass[1] + 0.05))
    assert not info["is_success"]  # nothing poured
    scene = TASK.scene({"marker_x": 0.47, "marker_y": 0.03})
    assert [(p.name, p.x, p.y) for p in scene.places] == [(objects.MARKER, 0.47, 0.03)]
    assert TASK.env_kwargs(scene)["marker_x"] == 0.47 and scene.space == SPACE


@pytest.mark.parametrize(("offsets", "expected"), [
    ((0.01, 0.02, 0.03), "success"), ((0.01, OVER + 0.001, 0.0), "off_marker"),
])
def test_a_pour_succeeds_only_over_the_marker(offsets, expected):
    replays = [{"pour_fraction": 1.0, "spilled": 0, "marker_offset": o, "min_distance_m": 0.01,
                "diverged": False} for o in offsets]
    assert outcome(0.01, replays, {"particles": 60}) == expected
    low = [{**r, "pour_fraction": 0.5, "spilled": 30} for r in replays]
    assert outcome(0.01, low, {"particles": 60}) == "spill"  # the pour's outcomes come first
    assert set(OUTCOMES) == {*get_task("pour").outcomes, "off_marker"}


def test_the_space_is_not_eq_1_but_holds_it():
    assert SPACE.m == 10 and SPACE.places == (objects.MARKER,)
    assert SPACE.terms[0] == EQ1.terms[0] and SPACE.terms[2:] == EQ1.terms[1:]
    assert TASK.dims[3:6] == ("glass_marker_dx", "glass_marker_dy", "glass_marker_dz")


def test_the_teacher_pours_over_the_marker():
    """Every demonstration of seed 0 holds the glass over the marker through the pour, the
    marker moved between demonstrations (each place seen where it stands, from the middle of
    the stillness before to the one after); the first one pours in physics (the pour's own
    check, on this script's motion)."""
    motion = script_demonstrations(TeacherConfig(task="marked"))
    spots = np.array([(p.x, p.y) for (p,) in motion.places])
    assert len(spots) == len(motion.boundaries) and len({tuple(s) for s in spots}) == len(spots)
    assert np.all(np.abs(spots - (MARKER_PLACE.x, MARKER_PLACE.y)) <= np.add(PLACE_SPREAD, 1e-9))
    for spot, (start, end) in zip(spots, motion.boundaries, strict=True):
        times = np.linspace(start, end, 200)
        _, u = motion.phase(times)
        pouring = (u >= SCRIPT.waypoints[4][0]) & (u <= SCRIPT.waypoints[5][0])
        glass = motion.poses(times[pouring])[objects.GLASS][0]
        assert np.hypot(*(glass[:, :2] - spot).T).max() < OVER
        np.testing.assert_array_equal(motion.place_poses(times)[objects.MARKER][0][:, :2],
                                      np.broadcast_to(spot, (len(times), 2)))
    assert teacher_pour(motion, 0, particles=30) >= 0.9


def test_a_quick_marked_run_end_to_end_tracks_the_marker_and_reports_its_keys(tmp_path):
    """``imitate run --task marked --quick``: the robot's eyes track the marker beside the
    objects, the model is learned in the task's own space, and the report holds every key the
    task declares."""
    from imitate.cli import main
    from imitate.demos.space_selection import candidates
    from imitate.rundir import layout
    from imitate.rundir.schema import check_values
    from imitate.stages.files import ModelFile, ObservationsFile, PlanFile
    from imitate.stages.runner import run_keys

    run_dir = tmp_path / "marked"
    assert main(["run", "--task", "marked", "--quick", "--out", str(run_dir)]) == 0
    observed = ObservationsFile.load(run_dir).observations
    assert observed.tracks.objects == (objects.BOTTLE, objects.GLASS, objects.MARKER)
    error = np.linalg.norm(observed.tracks.position[2] - observed.truth.position[2], axis=-1)
    assert np.nanmedian(error) < 0.03 and np.isfinite(error).mean() > 0.5  # small images: 27 mm
    assert ModelFile.load_learned(run_dir).model.mean.shape[1] == SPACE.m
    report = json.loads((run_dir / layout.REPORT).read_text())
    check_values(report, run_dir / layout.REPORT, *run_keys(TASK))
    assert report["replay"]["outcome"] in TASK.outcomes
    assert np.isfinite(report["replay"]["marker_offset"])
    assert report["learning"]["task_space"] == " ".join(f"({t})" for t in SPACE.text)
    assert report["learning"]["space_ratios"] == []

    # The space selected from the demonstrations: learned, planned and replayed in it.
    for stage in ("learn", "optimize", "replay"):
        assert main([stage, str(run_dir), *(["--task-space", "auto"] if stage == "learn"
                                             else [])]) == 0
    learned = ModelFile.load_learned(run_dir)
    report = json.loads((run_dir / layout.REPORT).read_text())
    assert learned.space is not None and learned.model.mean.shape[1] == learned.space.m
    assert report["learning"]["task_space"] == " ".join(f"({t})" for t in learned.space.text)
    assert {name for name, _ in report["learning"]["space_ratios"]} == {
        "tool-target", "tool-marker", "target-marker", "tool-world", "target-world",
        "tool-target@tool", "tool-target@target", "tool-marker@tool", "target-marker@target",
    }
    assert report["replay"]["outcome"] in TASK.outcomes

    # A space named by its relations (eq. 1's here): learned and planned in it.
    for stage in ("learn", "optimize"):
        assert main([stage, str(run_dir), *(["--task-space", "tool-target"] if stage == "learn"
                                             else [])]) == 0
    assert ModelFile.load_learned(run_dir).space == EQ1
    assert PlanFile.load(run_dir).plan.mean.shape[1] == EQ1.m

    # TP-GMM: learned in every frame, planned and replayed in the product's space.
    for stage in ("learn", "optimize", "replay"):
        assert main([stage, str(run_dir), *(["--task-space", "tpgmm"] if stage == "learn"
                                             else [])]) == 0
    learned = ModelFile.load_learned(run_dir)
    assert learned.frames and learned.space == candidates((objects.MARKER,), world=False,
                                                                   own_frames=False)
    assert learned.model.mean.shape[1] == learned.space.m == 13
    assert learned.task(TASK).space == SPACE  # the reproduction's space: the declared one here
    assert PlanFile.load(run_dir).plan.mean.shape[1] == SPACE.m
    assert json.loads((run_dir / layout.REPORT).read_text())["replay"]["outcome"] in TASK.outcomes



def test_no_obstacle_stands_over_the_marker():
    """Drawn in a path through the column over the marker and beside it, an obstacle keeps out
    of the column (as wide as the glass): it stands beside, in the path there."""
    from imitate.evaluation.suite import Suite
    from imitate.evaluation.variation import draw

    suite = Suite.default("marked").replace(in_path_share=1.0, obstacle_share=1.0,
                                            marker_x=[0.45, 0.45], marker_y=[0.0, 0.0])
    path = np.array([[0.45, 0.0, 0.72], [0.45, -0.22, 0.72]])  # over the marker, beside it
    reach = max(r for r, _ in objects.SHAPES[objects.GLASS].profile)
    drawn = [draw(suite, 0, i, path).obstacle for i in range(12)]
    assert all(o is not None for o in drawn)
    for o in drawn:
        apart = np.abs(np.subtract((0.45, 0.0), o.pos[:2]))
        gap = (np.hypot(*np.maximum(apart - o.size[:2], 0)) if o.shape == "box"
               else np.hypot(*apart) - o.size[0])
        assert gap >= reach
