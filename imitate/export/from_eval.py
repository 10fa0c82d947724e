"""Robot episodes from an evaluation: one per evaluated variation, for policies that need many.

An evaluation's records hold each variation's settings, not its plan or its steps, and both
follow from the settings and the teacher's learned model: the variation is planned again with
that model (checked against the record: the same clearance and iterations) and replayed in its
perturbed physics from its first replay seed, recorded (:func:`imitate.export.episodes.recorded`).
Its observations also hold the variation's obstacle and fixtures, ``obstacle``, ``shelf`` and
``plate`` ``(n + 1, 8)`` (:data:`~imitate.export.episodes.OBSTACLE`, zeros where it has none), the
same at every step: a policy sees what it must avoid.
The episode's ``metadata`` says what it is: ``teacher``, ``variation`` (the id), ``task`` (its
name), ``settings`` (the record's, :class:`~imitate.evaluation.variation.Variation`),
``outcome`` (the evaluation's, over all its replays and its plan's clearance) and the task's own
(its ``exported``: e.g. the evaluation's smallest score over the replays, this replay's measure
and whether it succeeded, the env's ``is_success``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from imitate.envs.task import get_task
from imitate.errors import ImitateError
from imitate.evaluation.record import TrialRecord
from imitate.evaluation.suite import Suite
from imitate.evaluation.suite_run import last_records
from imitate.evaluation.trial import physics, plan_variation
from imitate.evaluation.variation import Variation
from imitate.export.episodes import OBSTACLE, PLACES, Episode, image_kwargs, recorded
from imitate.export.episodes import obstacle_vector as vector
from imitate.run import Run
from imitate.rundir import layout
from imitate.rundir.artifacts import load_json
from imitate.stages import provenance
from imitate.stages.files import Learned, ModelFile
from imitate.stages.progress import bar as progress_bar

__all__ = ["Evaluated", "evaluated", "evaluated_episodes", "replayed"]


@dataclasses.dataclass(frozen=True, eq=False)
class Evaluated:
    """An evaluation's records with the teachers' models they were made with.

    Attributes:
        records: The last evaluation's records, by teacher and id.
        models: Teacher seed -> its learned model and gaze frame.
    """

    records: list[TrialRecord]
    models: dict[int, Learned]


def evaluated(run: Run, eval_dir: Path) -> Evaluated:
    """The last evaluation into ``eval_dir`` of ``run``'s teachers, checked to follow from the
    teachers' models as they are now and this code (the records' digests).

    Raises:
        ImitateError: no evaluation there, a teacher's model missing, or a digest that does not
            match (the message says to evaluate again).
    """
    eval_dir = Path(eval_dir)
    records = last_records(eval_dir)
    summary = load_json(eval_dir / "summary.json")
    evaluated_task = summary.get("task") if isinstance(summary, dict) else None
    if evaluated_task is not None and evaluated_task != run.config.task:
        raise ImitateError(
            f"{eval_dir} is an evaluation of task {evaluated_task!r}, the run of task "
            f"{run.config.task!r}: export it with the run it evaluated"
        )
    try:
        suite = Suite.from_dict(
            summary["suite"], source=str(eval_dir / "summary.json"), task=run.config.task
        )
        draw_seed, digests = summary["seed"], {t["seed"]: t["digest"] for t in summary["teachers"]}
        if not all(type(seed) is int for seed in digests):  # each names a folder
            raise TypeError(f"teacher seeds {list(digests)!r:.60} are not all whole numbers")
    except (KeyError, TypeError) as err:
        raise ImitateError(
            f"{eval_dir / 'summary.json'} is not an evaluation's summary ({type(err).__name__}: "
            f"{err}); run the evaluation again"
        ) from err
    models, code = {}, provenance.code_digest()
    for seed, digest in digests.items():
        folder = run.path if seed == run.config.seed else (
            run.path / "eval" / "teachers" / f"seed-{seed}"
        )
        path = folder / layout.MODEL
        learned = ModelFile.load_learned(folder)
        if suite.digest(draw_seed, seed, path.read_bytes(), code) != digest:
            raise ImitateError(
                f"{eval_dir} was evaluated with another model of teacher {seed} ({path}) or "
                f"other code; run the evaluation again (imitate eval {run.path} ...) to export it"
            )
        models[seed] = learned
    if not records:
        raise ImitateError(f"{eval_dir} holds no finished variation; run the evaluation first")
    return Evaluated(records, models)


def evaluated_episodes(
    run: Run, evaluation: Evaluated, images: bool = False, progress: bool | None = None
) -> Iterator[Episode]:
    """One robot episode per record of ``evaluation`` (see the module), in its order; with
    ``images`` the env's camera images at the run's size. ``progress``: a bar (``None``: on a
    terminal, else log lines; see :func:`~imitate.stages.progress.bar`).

    Raises:
        ImitateError: a variation's plan differs from the evaluated one.
    """
    task = get_task(run.config.task)
    for record in progress_bar(evaluation.records, progress, desc="export", unit="episode"):
        variation = Variation.from_json(record["settings"])
        teacher = record["teacher"]
        learned = evaluation.models[teacher]
        gaze, planned = learned.gaze, learned.task(task)
        plan = plan_variation(learned.planned, gaze, variation, planned)
        evaluated_plan = record["plan"]
        if (plan.min_distance, plan.n_iter) != (
            evaluated_plan["min_distance_m"], evaluated_plan["iterations"]
        ):
            raise ImitateError(
                f"variation {variation.id} of teacher {teacher} plans otherwise than it was "
                f"evaluated (clearance {plan.min_distance} m, {plan.n_iter} iterations against "
                f"{evaluated_plan['min_distance_m']} m, {evaluated_plan['iterations']})"
            )
        scene, pixels = variation.scene(planned), image_kwargs(run, images)
        kwargs: dict[str, Any] = {**planned.env_kwargs(scene), **pixels}
        episode = recorded(
            planned, plan, physics(variation, planned, **pixels), kwargs,
            variation.replay_seeds[0], planned.scene_reset(scene), gaze,
        )
        places = {
            place: np.tile(vector(getattr(variation, place)), (len(episode) + 1, 1))
            for place in PLACES
        }
        yield dataclasses.replace(
            episode,
            observations={**episode.observations, **places},
            names={**episode.names, **dict.fromkeys(PLACES, OBSTACLE)},
            environment=(*episode.environment, *PLACES),
            metadata={
                "teacher": teacher, "variation": variation.id, "task": task.name,
                "settings": record["settings"], "outcome": record["outcome"],
                **task.exported(record, {k: v[-1] for k, v in episode.infos.items()}),
            },
        )


def replayed(metadata: dict, actions: np.ndarray) -> dict:
    """An exported episode's ``actions`` ``(n, 18)`` [rad] stepped in its variation's physics
    from its reset (the ``metadata`` of :func:`evaluated_episodes`): its task's measures
    (``Task.measures``) and ``is_success`` after the last step, to check against the
    metadata."""
    task = get_task(metadata["task"])
    variation = Variation.from_json(metadata["settings"])
    env = physics(variation, task)
    try:
        env.reset(seed=variation.replay_seeds[0], options=task.scene_reset(variation.scene(task)))
        info: dict[str, Any] = {}
        for action in np.asarray(actions, dtype=np.float64):
            _, _, _, _, info = env.step(action)
    finally:
        env.close()
    return {**task.record(info), "is_success": info["is_success"]}
