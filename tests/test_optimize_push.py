"""The ``--push`` setting in the optimize stage: the plan at the chosen collision weight is
pushed only where the attractors alone leave less than the margin; the sweep never is."""

from __future__ import annotations

import numpy as np
import pytest

from imitate.demos.oracle import oracle_model
from imitate.envs.task import get_task
from imitate.learning import LearningConfig
from imitate.motion import PlanConfig
from imitate.motion.replay import planning_task
from imitate.rundir.artifacts import save_npz
from imitate.stages import optimize
from imitate.stages.config import RunConfig


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    """A folder with a model learned from the teacher's ground truth (``model.npz``)."""
    folder = tmp_path_factory.mktemp("push")
    gaze = planning_task().gaze
    model = oracle_model(gaze, learning=LearningConfig(k_max=12))  # smaller K: faster
    save_npz(folder / "model.npz", {**model.to_arrays(), "gaze": gaze})
    return folder


def _plans(run_dir, **settings) -> dict[bool, tuple[dict, dict]]:
    """``{push: (report, plan.npz's arrays)}`` of the optimize stage with ``--push`` and
    ``--no-push``."""
    found = {}
    for push in (True, False):
        config = RunConfig(push=push, max_iter=30, **settings)
        report = optimize.run(run_dir, config, get_task(config.task))
        with np.load(run_dir / "plan.npz") as arrays:
            found[push] = report["optimization"], dict(arrays)
    return found


def test_push_changes_nothing_where_the_attractors_keep_the_margin(run_dir):
    """At the default weight the attractors keep the margin: both plans are the same bytes."""
    plans = _plans(run_dir, sweep=(1.0,))
    (report, pushed), (_, plain) = plans[True], plans[False]
    assert report["min_distance_m"] >= PlanConfig().margin
    assert pushed.keys() == plain.keys()
    for name in pushed:
        assert np.array_equal(pushed[name], plain[name]), name


def test_push_keeps_the_margin_where_the_attractors_alone_do_not(run_dir):
    """At collision weight 300 (30 iterations) the attractors alone hit the chest: with the push
    the plan keeps the margin, without it the plan is the attractors' (the sweep's, which is
    never pushed)."""
    plans = _plans(run_dir, collision_weight=300.0, sweep=(0.5, 1.0))
    (report, pushed), (plain_report, plain) = plans[True], plans[False]
    assert plain_report["min_distance_m"] < PlanConfig().margin
    assert not np.any(plain["push"]) and "null-space push" not in plain_report["message"]
    assert report["min_distance_m"] >= PlanConfig().margin, report["message"]
    assert np.any(pushed["push"]) and "null-space push" in report["message"]
    assert not np.array_equal(pushed["q"], plain["q"])
    # the chosen weight's sweep entry is its plan; the other sweep plan is the same either way
    np.testing.assert_array_equal(pushed["sweep_q"][-1], pushed["q"])
    np.testing.assert_array_equal(plain["sweep_q"][-1], plain["q"])
    np.testing.assert_array_equal(pushed["sweep_q"][0], plain["sweep_q"][0])
