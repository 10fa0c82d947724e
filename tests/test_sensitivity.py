"""The measured tolerance's pieces: the move in the critical phase, its window, the tolerance of
failure rates, the quadratic form and the alignment."""

import numpy as np
import pytest

from imitate.evaluation import sensitivity as sens
from imitate.models import humanoid
from imitate.motion import Plan
from imitate.motion.replay import planning_task
from imitate.taskspace import EQ1


def _plan(task_map, steps: int = 9) -> Plan:
    """A plan that sweeps the right elbow and wrist a little, its task states from the map."""
    q = np.tile(humanoid.rest_pose(), (steps, 1))
    for name, amount in (("right_elbow", 0.3), ("right_wrist_pitch", 0.4)):
        q[:, humanoid.JOINTS.index(name)] += np.linspace(0.0, amount, steps)
    x, ref = [], np.zeros(2)
    for row in q:
        task_map.kin.update(row)
        state, _ = task_map(ref)
        ref = state[EQ1.angles]
        x.append(state)
    x = np.array(x)
    return Plan(
        times=0.08 * np.arange(steps), attractors=np.zeros((1, 7)), push=np.zeros((1, 18)),
        target=x, x=x, q=q, q_start=q[0], approach_bend=np.zeros(18), mean=x,
        variance=np.ones_like(x), covariance=np.tile(np.eye(7), (steps, 1, 1)),
        weights=np.ones_like(x), costs={}, min_distance=0.1,
        closest=None, converged=True, clipped=0, message="", n_iter=0, n_evaluations=0,
    )


@pytest.mark.parametrize("direction", [0, 2, 3, 6])
def test_a_move_moves_the_task_state_by_delta(direction):
    """Two tolerances along a task dimension: the task state moves by that, to first order
    (within 5 % of the move, the other dimensions within 5 % of it too), where the window is 1;
    not at all where it is 0."""
    task_map = planning_task()
    plan = _plan(task_map)
    ease = np.array([0, 0, 0.5, 1, 1, 1, 0.5, 0, 0], float)
    delta = 2.0 * np.eye(7)[direction] * EQ1.tolerance
    moved = sens.moved(plan, task_map, delta, ease)
    for t, w in enumerate(ease):
        task_map.kin.update(moved.q[t])
        x, _ = task_map(plan.x[t, EQ1.angles])
        change = (x - plan.x[t]) / EQ1.tolerance
        np.testing.assert_allclose(change, 2.0 * w * np.eye(7)[direction], atol=0.1)
    assert np.array_equal(moved.q[ease == 0], plan.q[ease == 0])


def test_window_is_one_in_the_critical_phase_and_eases_out():
    times = 0.1 * np.arange(20)
    critical = (times > 0.75) & (times < 1.25)
    ease = sens.window(times, critical, ramp=0.4)
    assert np.all(ease[critical] == 1.0) and np.all(ease[(times < 0.35) | (times > 1.65)] == 0)
    assert ease[7] == pytest.approx(0.5 + 0.5 * np.cos(np.pi * 0.1 / 0.4))
    assert np.all(np.diff(ease[:9]) >= 0) and np.all(np.diff(ease[12:]) <= 0)


@pytest.mark.parametrize(
    "rates, expected",
    [
        ([[0, 0, 0], [0, 0, 0]], np.inf),
        ([[0, 0, 1], [0, 0, 0]], 3.0),  # halfway from 2 (none failed) to 4 (all)
        ([[0, 0, 1], [0, 1 / 3, 2 / 3]], 3.0),  # the tighter side: both reach half at 3
        ([[0, 0, 0], [1, 1, 1]], 0.5),  # from 0 at no move
        ([[0, 2 / 3, 1], [0, 0, 0]], 1.75),
    ],
)
def test_tolerance_is_where_half_the_replays_fail(rates, expected):
    assert sens.tolerance(np.array(rates, float), (1.0, 2.0, 4.0)) == pytest.approx(expected)


def test_quadratic_form_holds_the_importances_it_can():
    """A form made of rank-one pieces of the probed directions is found again; every fit is
    positive semi-definite."""
    rng = np.random.default_rng(3)
    directions = sens.probe_directions(np.cov(rng.standard_normal((7, 30))))
    truth = np.einsum("i,ij,ik->jk", rng.uniform(0, 1, 14), directions, directions)
    importance = np.einsum("ij,jk,ik->i", directions, truth, directions)
    fitted = sens.quadratic_form(directions, importance)
    np.testing.assert_allclose(
        np.einsum("ij,jk,ik->i", directions, fitted, directions), importance, rtol=1e-6
    )
    noisy = sens.quadratic_form(directions, rng.uniform(-1, 1, 14))
    assert np.linalg.eigvalsh(noisy).min() > -1e-12


def test_probe_directions_are_the_axes_then_the_eigenvectors_most_agreed_first():
    covariance = np.diag([4.0, 1.0, 9.0, 0.5, 2.0, 3.0, 6.0])
    directions = sens.probe_directions(covariance)
    assert directions.shape == (14, 7)
    np.testing.assert_allclose(directions[:7], np.eye(7))
    np.testing.assert_allclose(np.abs(directions[7:]).argmax(axis=1), [3, 1, 4, 5, 0, 6, 2])
    assert np.all(directions[7:].max(axis=1) == 1.0)


@pytest.mark.parametrize("variances", [(4.0, 1.0, 9.0, 0.5, 2.0, 3.0, 6.0),
                                       (4.0, 1.0, 9.0, 0.5, 2.0, 3.0, 6.0, 8.0, 0.2, 5.0)])
def test_alignment_is_the_rank_correlation_of_precision_and_importance(variances):
    """Over eq. 1's 7 dimensions and a space of 10 (``marked``'s): the first m importances are
    the dimensions', the last m the eigen-directions'."""
    covariance = np.diag(variances)
    precision = 1.0 / np.diag(covariance)
    aligned = np.concatenate([precision, np.sort(precision)[::-1]])
    assert sens.alignment(covariance, aligned) == pytest.approx({"eigen": 1.0, "diagonal": 1.0})
    against = sens.alignment(covariance, -aligned)
    assert against == pytest.approx({"eigen": -1.0, "diagonal": -1.0})
    assert np.isnan(sens.alignment(covariance, np.zeros(2 * len(variances)))["eigen"])


def test_the_importance_weighting_reads_a_result_of_the_teachers_own_model(tmp_path):
    from imitate.errors import ImitateError
    from imitate.evaluation.teachers import Teacher
    from imitate.rundir.artifacts import save_json
    from imitate.stages.files import Learned

    teacher = Teacher(3, tmp_path / "model.npz", Learned(None, np.eye(3)), b"model", None)
    with pytest.raises(ImitateError, match="teacher 3's measured tolerance.*missing"):
        sens.with_importance(tmp_path, [teacher])
    form = np.diag(np.arange(1.0, 8.0))
    path = sens.result_path(tmp_path, 3)
    path.parent.mkdir()
    result = {"model": sens.model_digest(b"other"), "magnitudes": [1, 2, 4],
              "quadratic_form": form.tolist()}
    save_json(path, result)
    with pytest.raises(ImitateError, match="measured on another model than teacher 3's"):
        sens.with_importance(tmp_path, [teacher])
    save_json(path, {**result, "model": sens.model_digest(b"model"),
                     "quadratic_form": [[1.0, 2.0]]})
    with pytest.raises(ImitateError, match="holds no usable quadratic form"):
        sens.with_importance(tmp_path, [teacher])
    path.write_text('{"model": "cut sh')
    with pytest.raises(ImitateError, match="is corrupt"):
        sens.with_importance(tmp_path, [teacher])
    save_json(path, {**result, "model": sens.model_digest(b"model")})
    (read,) = sens.with_importance(tmp_path, [teacher])
    np.testing.assert_array_equal(read.learned.importance, form + np.eye(7) / 16)
    assert teacher.learned.importance is None  # the teacher given is left as it was
    assert read.digest_bytes != teacher.digest_bytes == b"model"  # its records are others


def test_the_command_measures_a_teacher_keeps_it_and_reuses_it(run_dir, capsys):
    """One move either way, one replay: the whole command, its result kept with the run."""
    import json

    from imitate.cli import main

    args = ["sensitivity", str(run_dir), "--magnitudes", "4", "--seeds", "1", "--workers", "2"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "| teacher | dx | dy | dz |" in out and "| 0 |" in out
    assert "alignment over 1 teacher(s): eigen median " in out
    result = json.loads(sens.result_path(run_dir, 0).read_text())
    assert result["model"] == sens.model_digest((run_dir / "model.npz").read_bytes())
    assert np.array(result["rates"]).shape == (14, 2, 1)
    assert np.all(np.linalg.eigvalsh(result["quadratic_form"]) >= -1e-9)
    assert (run_dir / "sensitivity" / "sensitivity.png").stat().st_size > 0
    written = sens.result_path(run_dir, 0).stat().st_mtime_ns
    assert main(args) == 0
    assert sens.result_path(run_dir, 0).stat().st_mtime_ns == written  # kept, not measured again
