"""Robot episodes from an evaluation: one per evaluated variation, for policies that need many.

An evaluation's records hold each variation's settings, not its plan or its steps, and both
follow from the settings and the teacher's learned model: the variation is planned again with
that model (checked against the record: the same clearance and iterations) and replayed in its
perturbed physics from its first replay seed, recorded (:func:`imitate.export.episodes.recorded`).
Its observations also hold the variation's obstacle and fixtures, ``obstacle``, ``shelf`` and
``plate`` ``(n + 1, 8)`` (:data:`~imitate.export.episodes.OBSTACLE`, zeros where it has none), the
same at every step: a policy sees what it must avoid.
The episode's ``metadata`` says what it is: ``teacher``, ``variation`` (the id), ``settings``
(the record's, :class:`~imitate.evaluation.variation.Variation`), ``outcome`` and ``pour_min``
(the evaluation's, over all its replays and its plan's clearance), ``pour_fraction`` and
``poured`` (this replay's: the env's ``is_success``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from imitate.errors import ImitateError
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

    records: list[dict]
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
    try:
        suite = Suite.from_dict(summary["suite"], source=str(eval_dir / "summary.json"))
        draw_seed, digests = summary["seed"], {t["seed"]: t["digest"] for t in summary["teachers"]}
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
        if suite.digest(draw_seed, path.read_bytes(), code) != digest:
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
    for record in progress_bar(evaluation.records, progress, desc="export", unit="episode"):
        variation = Variation.from_json(record["settings"])
        teacher = record["teacher"]
        gaze = evaluation.models[teacher].gaze
        plan = plan_variation(evaluation.models[teacher].model, gaze, variation)
        evaluated_plan = record["plan"]
        if (plan.min_distance, plan.n_iter) != (
            evaluated_plan["min_distance_m"], evaluated_plan["iterations"]
        ):
            raise ImitateError(
                f"variation {variation.id} of teacher {teacher} plans otherwise than it was "
                f"evaluated (clearance {plan.min_distance} m, {plan.n_iter} iterations against "
                f"{evaluated_plan['min_distance_m']} m, {evaluated_plan['iterations']})"
            )
        scene, pixels = variation.scene(), image_kwargs(run, images)
        kwargs: dict[str, Any] = {
            "particles": scene.particles,
            "obstacles": [dataclasses.asdict(o) for o in scene.obstacles],
            **pixels,
        }
        options = {"bottle_grasp": variation.bottle_grasp, "glass_grasp": variation.glass_grasp}
        episode = recorded(
            plan, physics(variation, **pixels), kwargs, variation.replay_seeds[0], options, gaze
        )
        places = {
            place: np.tile(vector(getattr(variation, place)), (len(episode) + 1, 1))
            for place in PLACES
        }
        yield dataclasses.replace(
            episode,
            observations={**episode.observations, **places},
            names={**episode.names, **dict.fromkeys(PLACES, OBSTACLE)},
            metadata={
                "teacher": teacher, "variation": variation.id, "settings": record["settings"],
                "outcome": record["outcome"], "pour_min": record["pour_min"],
                "pour_fraction": float(episode.infos["pour_fraction"][-1]),
                "poured": bool(episode.infos["is_success"][-1]),
            },
        )


def replayed(metadata: dict, actions: np.ndarray) -> dict:
    """An exported episode's ``actions`` ``(n, 18)`` [rad] stepped in its variation's physics
    from its reset (the ``metadata`` of :func:`evaluated_episodes`): ``{"pour_fraction",
    "spilled", "is_success"}`` after the last step, to check against the metadata."""
    variation = Variation.from_json(metadata["settings"])
    env = physics(variation)
    try:
        env.reset(seed=variation.replay_seeds[0], options={
            "bottle_grasp": variation.bottle_grasp, "glass_grasp": variation.glass_grasp,
        })
        info: dict[str, Any] = {}
        for action in np.asarray(actions, dtype=np.float64):
            _, _, _, _, info = env.step(action)
    finally:
        env.close()
    return {key: info[key] for key in ("pour_fraction", "spilled", "is_success")}
