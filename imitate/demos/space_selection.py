"""What to imitate, from the demonstrations' statistics: candidate position terms, each one's
invariance where the task is decided, and the task space they select.

The candidates (:func:`candidates`) are every relation the tracks can give: the tool relative to
the target (eq. 1's), and each held object relative to each place of the scene and to the world
(the robot's frame, :data:`~imitate.taskspace.WORLD`: the robot's base is fixed), those not to the
world also in the own frame of each held object they join (``tool-target@target``), beside eq. 1's
angles. The world is rated, never kept: the teacher works across the table, so where it held the
objects in the robot's frame is out of the robot's reach (a relation to it cannot be reproduced).
The demonstrations in that space are aligned by DTW (:func:`imitate.learning.dtw.align`, as
learning aligns them). A term's **invariance ratio** (:func:`invariance`) is the aligned
demonstrations' spread across one another in the critical phase (the trace of their covariance at
each of its samples, averaged) over the term's whole spread (the trace of the covariance of all its
samples): small where the demonstrations agree on it while it moves over the movement, the variance
criterion the paper's authors followed up with. A relation in an object's own frame is the same
vector turned, of the same length at every sample: its frame's own turning over the movement is not
the relation's movement, so its ratio is over the whole spread of its twin in the world's frame,
and the two frames' ratios differ only by where the demonstrations agree.

:func:`select` keeps the tool's most invariant relation (to the target or a place), the target's
most invariant relation to a place (its relation to the tool is the tool's) only where its ratio
is under :data:`INVARIANT`, and eq. 1's angles of both objects. A relation in an object's own
frame competes only where the demonstrations agree in it beyond chance (:func:`own_frame_bound`:
its ratio under that share of its world twin's): it rests on the tracked axes too, and where the
object hardly turns it holds what the world's does. :func:`named` gives a space by its
relations' names instead (``--task-space tool-target``: eq. 1's; ``tool-target@tool``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import scipy.stats

from imitate.demos.segment import Demonstration, place_positions, task_demo
from imitate.envs.task import Task
from imitate.errors import ImitateError
from imitate.learning.dtw import align
from imitate.taskspace import OBJECTS, WORLD, Angles, Relative, TaskSpace

__all__ = ["INVARIANT", "aligned", "candidates", "equivalent", "invariance", "named",
           "own_frame_bound", "rate", "select", "spread", "spreads"]

# The largest invariance ratio of a relation of the target's kept (the demonstrations spread in
# the critical phase by under a tenth of its spread over the movement). Chosen on teachers 0-2 of
# a task with a place (the place's ratio 0.02-0.05) and one without (the world's 0.25-0.33).
INVARIANT = 0.1


def own_frame_bound(demos: int) -> float:
    """The largest share of a relation's spread (variance) across ``demos`` demonstrations in
    the world's frame that its spread in an object's own frame may have for the own frame to
    compete: the 5 % quantile of the ratio of two variances of ``demos`` draws each, ``1 /
    F(0.95; demos - 1, demos - 1)`` (0.156 for five). Conservative: the two frames' spreads come
    from the same demonstrations and average over the critical phase's samples.

    Raises:
        ImitateError: fewer than two demonstrations (no spread).
    """
    if demos < 2:
        raise ImitateError(f"{demos} demonstrations have no spread to compare frames by: give 2 "
                           "or more")
    return float(1.0 / scipy.stats.f.ppf(0.95, demos - 1, demos - 1))


def candidates(places: Sequence[str], world: bool = True, own_frames: bool = True) -> TaskSpace:
    """The candidate terms of a task with ``places``: the tool relative to the target, the tool
    and the target relative to each place and (with ``world``) to the world, in the world's
    frame; then (with ``own_frames``) those not to the world in each held object's own frame
    they join; then eq. 1's angles."""
    tool, target = OBJECTS
    ends = (*places, WORLD) if world else tuple(places)
    relations = (Relative(tool, target), *(Relative(obj, p) for p in ends for obj in OBJECTS))
    framed = (Relative(r.of, r.to, own) for r in relations if r.to != WORLD and own_frames
              for own in OBJECTS if own in (r.of, r.to))
    return TaskSpace((*relations, *framed, Angles(tool), Angles(target)))


def invariance(values: np.ndarray, space: TaskSpace, critical: np.ndarray) -> dict[Relative, float]:
    """Each position term's invariance ratio (see the module): the square of the quotient of its
    :func:`spreads` (a relation in an object's frame: of its world twin's whole spread).

    Args:
        values: The demonstrations in ``space``, aligned, ``(n_demos, samples, m)``.
        space: Their space (its :class:`Relative` terms are rated).
        critical: ``(samples,)`` bool, the critical phase's samples.

    Raises:
        ImitateError: no sample in the critical phase.
    """
    parts = spreads(values, space, critical)
    world = {term: parts.get(Relative(term.of, term.to), parts[term]) for term in parts}
    return {term: (parts[term][0] / world[term][1]) ** 2 for term in parts}


def spreads(
    values: np.ndarray, space: TaskSpace, critical: np.ndarray
) -> dict[Relative, tuple[float, float]]:
    """Each position term's spread across the demonstrations in the critical phase (the root of
    the mean over its samples of :func:`spread` squared) and over the whole movement (the root of
    the trace of the covariance of all its samples), both [m]; arguments as :func:`invariance`.

    Raises:
        ImitateError: no sample in the critical phase.
    """
    if not np.any(critical):
        raise ImitateError("the critical phase holds no sample: nothing to rate the terms by")
    return {term: (float(np.sqrt(np.mean(across[critical] ** 2))), float(np.sqrt(
                np.trace(np.cov(values[:, :, space.columns(term)].reshape(-1, 3).T)))))
            for term, across in spread(values, space).items()}


def spread(values: np.ndarray, space: TaskSpace) -> dict[Relative, np.ndarray]:
    """Each position term's spread across the aligned demonstrations ``values`` ``(n_demos,
    samples, m)`` in ``space`` at each sample: ``sqrt`` of the trace of their covariance
    ``(samples,)`` [m]."""
    return {term: np.sqrt([np.trace(np.cov(x.T)) for x in values[:, :, space.columns(term)]
                           .transpose(1, 0, 2)])
            for term in space.terms if isinstance(term, Relative)}


def aligned(
    segments: Sequence[Demonstration], objects: tuple[str, ...], gaze: np.ndarray, task: Task,
    *, smoothing: float,
) -> tuple[np.ndarray, TaskSpace, np.ndarray]:
    """A teacher's cut demonstrations ``segments`` (of ``objects``, seen with ``gaze``, smoothed
    as learning smooths them) in every candidate term (the places where each demonstration saw
    them), aligned by DTW ``(n_demos, samples, m)``; the candidates; the critical phase's samples
    ``(samples,)`` bool (``task``'s, of their mean in its declared space)."""
    rate_hz = 1.0 / float(np.median(np.diff(segments[0].times)))
    space = candidates(task.space.places)
    values = align([
        task_demo(d, objects, gaze, space, p, smoothing=smoothing, rate=rate_hz)
        for d, p in zip(segments, place_positions(segments, objects), strict=True)
    ]).aligned
    return values, space, task.critical(values.mean(axis=0)[:, space.part_columns(task.space)])


def rate(
    segments: Sequence[Demonstration], objects: tuple[str, ...], gaze: np.ndarray, task: Task,
    *, smoothing: float,
) -> dict[Relative, float]:
    """The candidates' invariance ratios of a teacher's cut demonstrations (:func:`aligned`'s
    arguments)."""
    return invariance(*aligned(segments, objects, gaze, task, smoothing=smoothing))


def select(
    ratios: Mapping[Relative, float], demos: int, invariant: float = INVARIANT
) -> TaskSpace:
    """The task space ``ratios`` (:func:`invariance` of :func:`candidates` over ``demos``
    demonstrations) point to: the tool's relation of the lowest ratio, the target's to a place of
    the lowest ratio if it is under ``invariant``, then eq. 1's angles (relations to the world
    aside, and those in an object's frame under :func:`own_frame_bound` of their world twin's
    ratio: see the module)."""
    tool, target = OBJECTS
    bound = own_frame_bound(demos)
    ratios = {t: r for t, r in ratios.items() if t.to != WORLD and (
        not t.frame or r < bound * ratios.get(Relative(t.of, t.to), 0.0))}
    own = {t: r for t, r in ratios.items() if t.of == tool}
    if not own:
        raise ImitateError(f"no relation of the tool among {[str(t) for t in ratios]}")
    terms: list[Relative | Angles] = [min(own, key=own.__getitem__)]
    placed = {t: r for t, r in ratios.items() if t.of == target}
    if placed and min(placed.values()) < invariant:
        terms.append(min(placed, key=placed.__getitem__))
    return TaskSpace((*terms, Angles(tool), Angles(target)))


def named(text: str, places: Sequence[str]) -> TaskSpace:
    """The space of the relations ``text`` names, ``OF-TO`` or ``OF-TO@FRAME`` joined by ``+``
    (of the :func:`candidates` of a task with ``places``, the world's aside), then eq. 1's
    angles: ``tool-target`` is eq. 1, ``tool-target+target-marker`` ``marked``'s declared
    space, ``tool-target@target`` the tool in the target's own frame.

    Raises:
        ImitateError: an unknown relation, or one named twice.
    """
    relations = {t.name: t for t in candidates(places, world=False).terms
                 if isinstance(t, Relative)}
    names = text.split("+")
    if any(n not in relations for n in names) or len(set(names)) < len(names):
        raise ImitateError(
            f"task space {text!r} not accepted: declared, auto, tpgmm, or relations of "
            f"{list(relations)} joined by '+', each once (e.g. {'+'.join(relations)})"
        )
    return TaskSpace((*(relations[n] for n in names), *(Angles(o) for o in OBJECTS)))


def equivalent(a: TaskSpace, b: TaskSpace) -> bool:
    """Whether ``a`` and ``b`` hold the same of the demonstrations: the angles of the same
    objects, the same relations in objects' own frames, and relations in the world's frame
    joining the same objects and places (each space's positions a linear map of the other's:
    ``tool - marker`` and ``target - marker`` give ``tool - target``)."""

    def parts(space: TaskSpace) -> tuple[frozenset, frozenset, frozenset]:
        joined: list[set[str]] = []
        framed = frozenset(t for t in space.terms if isinstance(t, Relative) and t.frame)
        for term in space.terms:
            if isinstance(term, Relative) and not term.frame:
                touching = [g for g in joined if {term.of, term.to} & g]
                merged = set().union({term.of, term.to}, *touching)
                joined = [g for g in joined if g not in touching] + [merged]
        angles = frozenset(t.of for t in space.terms if isinstance(t, Angles))
        return angles, framed, frozenset(frozenset(g) for g in joined)

    return parts(a) == parts(b)
