"""``Task``: what makes a task the task, as one value the generic layers receive.

The learner, the tracker, the planner, the stages, the evaluation and the exports know a task
only through this value (:func:`get_task`): its objects (the tool, moved to the
target), its env, its task space, its own settings, how a replay is measured and
judged, and its critical phase.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, ClassVar, Protocol

import numpy as np

from imitate.envs import tasks
from imitate.envs.assembly import Obstacle, SceneConfig
from imitate.envs.bimanual import BimanualEnv
from imitate.rundir.page import Words, error_keys
from imitate.taskspace import EQ1, OBJECTS, TaskSpace

__all__ = ["Score", "Task", "Watcher", "get_task", "shared_outcome"]


class Watcher(Protocol):
    """Watches a replay: called with the env after its reset and after every step.

    Attributes:
        KEYS: What :meth:`summary` returns: each key with its unit and meaning.
    """

    KEYS: ClassVar[Mapping[str, tuple[str, str]]]

    def __call__(self, env: Any) -> None: ...

    def summary(self) -> dict[str, Any]:
        """What it saw, for the report."""
        ...


@dataclass(frozen=True)
class Score:
    """The replay measure a task's success is judged by, higher being better: a reproduction
    succeeds only if every replay's reaches ``threshold`` (and nothing touched or diverged).

    Attributes:
        measure: Its key in a replay's record (one of ``Task.measures``); the task's report
            lists the replays' values as ``<measure>s``.
        threshold: The least value of a success, in the measure's unit.
        name: Its short name in the evaluation's keys and text: a variation's record holds
            ``<name>_mean`` and ``<name>_min`` over its replays.
        unit: The unit it is shown in to people; ``""`` for a fraction (0..1, shown as is).
        scale: Its value times this is in ``unit`` (1000 for a length in m shown in mm).
    """

    measure: str
    threshold: float
    name: str
    unit: str = ""
    scale: float = 1.0

    @property
    def label(self) -> str:
        """Its name with the unit shown, ``"insert [mm]"``; a fraction's name alone."""
        return f"{self.name} [{self.unit}]" if self.unit else self.name

    def show(self, value: float) -> str:
        """``value`` (in the measure's unit) as shown: a fraction to 2 decimals, else in
        ``unit`` to 1."""
        return f"{value * self.scale:.1f}" if self.unit else f"{value:.2f}"


@dataclass(frozen=True)
class Task:
    """A bimanual task (see the module docstring).

    Attributes:
        env: Its env class; its ``objects`` are the tool (right hand) and the target (left),
            its ``task`` the task's name (one of ``imitate.envs.tasks.NAMES``), its
            ``measures`` what a replay's record adds (from ``info`` at the end).
        phase: The name of its critical phase (report keys ``<phase>_phase_err_m``).
        outcomes: The outcomes of a reproduction, ``"success"`` first.
        outcome: ``outcome(plan_min_distance [m], records, options) -> str``, one of
            ``outcomes``.
        critical_steps: ``critical_steps(mean (T, m), space) -> (T,) bool``: the steps of a
            learned mean in ``space`` in the task's critical phase (where its success is
            decided); :meth:`critical` in its own space.
        watcher: The :class:`Watcher` of a replay (a class: its ``KEYS`` are read).
        score: The replay measure its success is judged by (:class:`Score`).
        words: What its pages and datasets say of it (:class:`~imitate.rundir.page.Words`).
        exported: ``exported(record, info) -> dict``: the task's part of the metadata of an
            exported episode of an evaluated variation, from the evaluation's record of the
            variation and the env's ``info`` after the episode's last step.
        replays: Physics replays per reproduction, each from its own seed; the outcome asks
            every one to succeed.
        space: Its task space (:class:`~imitate.taskspace.TaskSpace`), over its objects' roles
            and places in its scene; eq. 1 unless declared.
    """

    env: type[BimanualEnv]
    phase: str
    outcomes: tuple[str, ...]
    outcome: Callable[[float, Sequence[Mapping[str, Any]], Mapping[str, Any]], str]
    critical_steps: Callable[[np.ndarray, TaskSpace], np.ndarray]
    watcher: type[Watcher]
    score: Score
    words: Words
    exported: Callable[[Mapping[str, Any], Mapping[str, Any]], dict[str, Any]]
    replays: int = 3
    space: TaskSpace = EQ1

    @property
    def name(self) -> str:
        """Its name (its env's ``task``)."""
        return self.env.task

    def critical(self, mean: np.ndarray) -> np.ndarray:
        """The steps ``(T,) bool`` of a learned mean ``(T, m)`` in its space in its critical
        phase (:attr:`critical_steps`)."""
        return self.critical_steps(mean, self.space)

    def in_space(self, space: TaskSpace) -> Task:
        """The task learned, planned and measured in ``space`` (a space selected from the
        demonstrations, say) instead of its declared one."""
        return replace(self, space=space)

    @property
    def env_id(self) -> str:
        """Its Gymnasium id (its ``options`` module's ``ENV_ID``)."""
        return str(tasks.module(self.name, "options").ENV_ID)

    @property
    def measures(self) -> Mapping[str, tuple[str, str]]:
        """The keys of a replay's record that it adds, with unit and meaning (its env's)."""
        return self.env.measures

    @property
    def suites(self) -> Path:
        """The folder of its evaluation suites (``*.toml``): ``suites`` in its package."""
        return tasks.folder(self.name) / "suites"

    @property
    def objects(self) -> tuple[str, str]:
        """The tool and the target (body names)."""
        return self.env.objects

    @property
    def dims(self) -> tuple[str, ...]:
        """Labels of its task space's columns in figures and exports, in its objects' names
        (``bottle_angle``)."""
        return self.space.labels(dict(zip(OBJECTS, self.objects, strict=True)))

    @property
    def keys(self) -> dict[str, tuple[str, str]]:
        """The report keys it adds (``replay.*``, :meth:`report`'s), with unit and meaning: its
        measures, the score's over the replays and its watcher's."""
        measure, score, n = self.score.measure, self.score, self.replays
        unit = self.measures[measure][0]
        least = score.show(score.threshold) + (f" {score.unit}" if score.unit else "")
        return {
            **{f"replay.{key}": value for key, value in self.measures.items()},
            f"replay.{measure}_mean": (unit, f"its mean over {n} replays from seeds `seed` to "
                                             f"`seed + {n - 1}` of the initial-state noise"),
            f"replay.{measure}_min": (unit, f"the smallest of them ({least} or more: success)"),
            f"replay.{measure}s": (unit, f"the {n}"),
            **{f"replay.{self.phase}_geometry.{key}": value
               for key, value in self.watcher.KEYS.items()},
        }

    @property
    def kinds(self) -> dict[str, type | tuple[type, ...]]:
        """The kind of each of its report keys (:attr:`keys`) whose value is no number: a
        count's (unit ``-``) ``int``, the score's list over the replays."""
        counts = {f"replay.{key}": int for key, (unit, _) in self.measures.items() if unit == "-"}
        return {**counts, f"replay.{self.score.measure}s": list}

    @property
    def error_keys(self) -> tuple[str, str]:
        """The report's (and a plan record's) keys of a plan's largest position [m] and angle
        [deg] error in the critical phase: ``<phase>_phase_err_m``, ``<phase>_phase_err_deg``."""
        return error_keys(self.phase)

    @property
    def options(self) -> dict[str, tasks.Option]:
        """Its own run settings (:func:`imitate.envs.tasks.options`): ``<object>_grasp`` for
        each object (the env's reset options), the others scene values (fields of
        ``SceneConfig`` and arguments of its env, such as pouring's ``particles``)."""
        return tasks.options(self.name)

    def settings(self, options: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Its own settings: the defaults with ``options`` replacing some of them, checked
        (:func:`imitate.envs.tasks.settings`)."""
        return tasks.settings(self.name, options)

    def report(
        self, records: Sequence[Mapping[str, Any]], watched: Mapping[str, Any]
    ) -> dict[str, Any]:
        """The task's keys of the report's replay section, from the replays' records (the
        ``measures``, ``min_distance_m``, ``diverged``) and the first replay's :class:`Watcher`
        summary: the first replay's measures, the score's measure over the replays
        (``<measure>_mean``, ``<measure>_min``, ``<measure>s``) and ``<phase>_geometry``."""
        measure = self.score.measure
        values = [r[measure] for r in records]
        return {
            **{key: records[0][key] for key in self.measures},
            f"{measure}_mean": float(np.mean(values)),
            f"{measure}_min": float(np.min(values)),
            f"{measure}s": values,
            f"{self.phase}_geometry": dict(watched),
        }

    def reset_options(self, options: Mapping[str, Any] | None = None) -> dict[str, float]:
        """The env's reset options (the grasps) for these settings."""
        values = self.settings(options)
        return {f"{obj}_grasp": values[f"{obj}_grasp"] for obj in self.objects}

    def scene_reset(self, scene: SceneConfig) -> dict[str, float]:
        """The env's reset options (the grasps) of ``scene``."""
        return {f"{obj}_grasp": float(g) for obj, g in zip(self.objects, scene.grasps, strict=True)}

    def env_kwargs(self, scene: SceneConfig) -> dict[str, Any]:
        """The kwargs of its env of ``scene`` as an env spec records them (JSON-ready): the
        task's own scene values and the obstacles as dicts; the grasps are reset options
        (:meth:`scene_reset`) and the teacher is left out (absent: the env's default)."""
        return {
            **self._scene_values(scene),
            "obstacles": [asdict(o) for o in scene.obstacles],
        }

    def scene(
        self,
        options: Mapping[str, Any] | None = None,
        obstacles: Sequence[Obstacle] = (),
        teacher: bool = False,
    ) -> SceneConfig:
        """The scene of these settings, ``obstacles`` and (or not) the teacher: its env's
        (:meth:`~imitate.envs.bimanual.BimanualEnv.scene_config`), at the settings' grasps."""
        values = self.settings(options)
        grasps = tuple(float(values[f"{obj}_grasp"]) for obj in self.objects)
        config = self.env.scene_config(teacher, tuple(obstacles), **self._scene_values(values))
        return replace(config, grasps=grasps, space=self.space)

    def make_env(self, scene: SceneConfig, **kwargs: Any) -> BimanualEnv:
        """Its env of ``scene`` (obstacles, teacher and the task's own scene values; the grasps
        are reset options), with the env's other arguments ``kwargs``."""
        return self.env(
            obstacles=scene.obstacles, teacher=scene.teacher, **self._scene_values(scene), **kwargs
        )

    def record(self, info: Mapping[str, Any]) -> dict[str, Any]:
        """The task's measures of a replay, from the env's ``info`` at its end."""
        return {key: info[key] for key in self.measures}

    def _scene_values(self, values: Mapping[str, Any] | SceneConfig) -> dict[str, Any]:
        """The scene values (beyond the grasps) of settings or of a scene, as its env takes
        them: its contents' (the particles), each place's ``<place>_x`` and ``<place>_y``."""
        names = [n for n in self.options if not n.endswith("_grasp")]
        if isinstance(values, Mapping):
            return {name: values[name] for name in names}
        found = {f"{p.name}_{c}": getattr(p, c) for p in values.places for c in "xy"}
        for content in values.contents:
            found.update(content.settings)
        return {name: found[name] for name in names}


def shared_outcome(plan_min_distance: float, replays: Sequence[Mapping[str, Any]]) -> str | None:
    """The outcomes every task's outcome checks first, in this order: ``diverged`` (a replay's
    physics blew up), ``plan_collision`` (the plan itself comes closer than 0 to something),
    ``physics_contact`` (the plan keeps clear, a replay does not); ``None`` if none applies and
    the task's own measures decide."""
    if any(r["diverged"] for r in replays):
        return "diverged"
    if plan_min_distance < 0:
        return "plan_collision"
    if min(r["min_distance_m"] for r in replays) < 0:
        return "physics_contact"
    return None


def get_task(name: str) -> Task:
    """The task ``name`` (one of ``imitate.envs.tasks.NAMES``; imports its package).

    Raises:
        ImitateError: an unknown name, with the known ones.
    """
    return tasks.module(name, "task").TASK
