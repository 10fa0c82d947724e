"""The teacher: scripted bimanual demonstrations of a task, and the mannequin that performs them.

:func:`script_demonstrations` draws ``n_demos`` movements of a task's :class:`Script` (its
nominal waypoints, each with its spread) as a person would repeat them: spread where the script
spreads them, each on its own smooth monotone time warp, with a little tremor throughout and at
least one second of stillness between demonstrations; or, with
``TeacherConfig(variation="misaligned")``, the nominal everywhere but in the task's critical
phase, whose position varies by centimetres (a teacher whose variance is not where the task is);
or, with ``"misleading"``, as the script spreads them and, in the critical phase, by a few
degrees more along a direction the task tolerates only while nothing pulls the reproduction
along it (a teacher whose variance frees what a constraint then takes); or, with ``"coupled"``,
as the script spreads them and, in the critical phase, both objects moved together by
centimetres (the target, and the tool relative to it: only their difference is invariant).
The result, a :class:`TeacherMotion`, gives the ground-truth object poses at any time;
:func:`imitate.envs.mannequin.show` puts the objects there and draws the mannequin's arms
holding them.

The teacher holds the tool in its left hand, which the robot facing it sees on its own right
(mirror correspondence), and tilts the tool's top towards the target (world ``+y``).

The mannequin's arms are drawn by :mod:`imitate.envs.mannequin`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from scipy.interpolate import CubicHermiteSpline, PchipInterpolator
from scipy.spatial.transform import Rotation

from imitate import defaults
from imitate.envs import tasks
from imitate.envs.assembly import Place
from imitate.errors import ImitateError
from imitate.models import shapes

TEACHER_VARIATIONS = defaults.TEACHER_VARIATIONS
_TASK_COLUMNS = slice(3, 8)  # target tilt, top - rim (3), tool tilt: what moves the task space
_WARP_GRID = 2001  # samples of a demonstration's time warp
_TREMOR_BAND = (6.0, 11.0)  # [Hz], physiological tremor
_TREMOR_WAVES = 6  # sinusoids summed per tremor channel


@dataclass(frozen=True)
class Script:
    """A task's demonstration as nominal waypoints in a demonstration's phase ``u`` in [0, 1].

    Attributes:
        objects: the tool and the target (names of :data:`imitate.models.shapes.SHAPES`).
        waypoints: rows ``(u, target bottom (3) [m], target tilt towards the tool [deg], tool
            top relative to the target's rim centre (3) [m], tool tilt towards the target
            [deg], spreads)``, the spreads one standard deviation over demonstrations of
            ``(target bottom, target tilt, tool top (one value or per axis x, y, z), tool
            tilt)``; the first and last rows are the rest pose, shared with the previous and
            next demonstration.
        swing_rows: rows through which a demonstration's tool top varies as a whole (one draw).
        agree_rows: the first and last row of the critical phase, where the demonstrations
            agree (the target keeps its offset from the nominal through it).
        offset_axis: the waypoints' column (of target bottom x, y, z, target tilt, tool top
            x, y, z, tool tilt) along which ``"misaligned"`` demonstrations are offset in the
            critical phase.
        mislead: ``(column, half range)``: the waypoints' column along which ``"misleading"``
            demonstrations are offset in the critical phase, and the half range [m or deg, as
            the column] their offsets spread evenly over; ``None`` where the task declares
            none.
        couple: ``(axis, half range)``: the world axis (0-2: x, y, z) along which
            ``"coupled"`` demonstrations move the target, and the tool with it, in the critical
            phase, and the half range [m] their offsets spread evenly over; ``None`` where the
            task declares none.
        places: objects standing still on the table in the teacher's scene, watched by the
            robot as the held ones are (the places a task space may be relative to).
        place_spread: half the ranges ``(x, y)`` [m] over which the places stand, from one
            demonstration to the next (they are moved in the stillness between two); zeros:
            where ``places`` puts them, throughout.
        placed_rows: the rows in which the target is placed relative to the places: its bottom
            moves with them (and the tool, relative to it, too).
    """

    objects: tuple[str, str]
    waypoints: tuple[tuple, ...]
    swing_rows: tuple[int, ...]
    agree_rows: tuple[int, int]
    offset_axis: int
    mislead: tuple[int, float] | None = None
    couple: tuple[int, float] | None = None
    places: tuple[Place, ...] = ()
    place_spread: tuple[float, float] = (0.0, 0.0)
    placed_rows: tuple[int, ...] = ()


@dataclass(frozen=True)
class TeacherConfig:
    """How the teacher demonstrates.

    Attributes:
        n_demos: number of demonstrations.
        duration: range ``(low, high)`` [s] each demonstration's duration is drawn from.
        pause: range ``(low, high)`` [s] of the stillness between demonstrations; also the
            stillness before the first and after the last demonstration is drawn from it.
        task: the task demonstrated (its :class:`Script`), one of ``imitate.envs.tasks.NAMES``.
        spread: scale of the spatial variation between demonstrations: 1 gives the spreads of
            the script's waypoints and its places' ``place_spread``.
        tilt_plane_spread: standard deviation of the azimuth of the plane the tool tilts in
            [rad] (0: it tilts straight across the robot's view).
        speed_variation: amplitude of the time warp: the local speed is
            ``1 +- speed_variation`` times a demonstration's mean speed, in [0, 0.9].
        tremor: standard deviation of the hands' tremor, positions [m].
        tremor_angle: standard deviation of the tremor of the tilt angles [rad].
        variation: where the demonstrations vary (:data:`TEACHER_VARIATIONS`): ``"aligned"``
            (as the script's spreads say: they agree where the task is) or ``"misaligned"``
            (the nominal outside the critical phase, the tool's position in it spread by
            ``offset``: they agree where the task is not), to test the premise that what the
            demonstrations keep invariant is what matters; or ``"misleading"`` (as
            ``"aligned"``, and in the critical phase offset along the script's ``mislead``
            direction: they vary where the task tolerates it unless pulled, a test of the
            premise's other side); or ``"coupled"`` (as ``"aligned"``, and in the critical
            phase the target, with the tool relative to it, offset along the script's
            ``couple`` axis: the objects vary together, their difference does not).
        offset: with ``"misaligned"``, the half range [m] the tool top's offsets along the
            script's ``offset_axis`` spread evenly over in the critical phase (times
            ``spread``).
        seed: seed of the ``numpy.random.Generator`` everything is drawn from.
    """

    n_demos: int = 5
    task: str = tasks.DEFAULT
    duration: tuple[float, float] = (4.0, 5.0)
    pause: tuple[float, float] = (1.2, 1.6)
    spread: float = 1.0
    tilt_plane_spread: float = np.radians(4.0)
    speed_variation: float = 0.25
    tremor: float = 0.0004
    tremor_angle: float = np.radians(0.15)
    variation: str = defaults.TEACHER_VARIATION
    offset: float = 0.025
    seed: int = 0

    def __post_init__(self):
        if not isinstance(self.n_demos, int | np.integer) or self.n_demos < 1:
            raise ImitateError(f"n_demos={self.n_demos!r} not accepted: an integer >= 1")
        for name in ("duration", "pause"):
            low, high = getattr(self, name)
            if not 0 < low <= high:
                raise ImitateError(
                    f"{name}={getattr(self, name)!r} not accepted: a range (low, high) [s] "
                    f"with 0 < low <= high"
                )
        if not 0 <= self.speed_variation <= 0.9:
            raise ImitateError(
                f"speed_variation={self.speed_variation!r} not accepted: a value in [0, 0.9] "
                f"(the time warp must stay monotone)"
            )
        if self.variation not in TEACHER_VARIATIONS:
            raise ImitateError(
                f"variation={self.variation!r} not accepted: one of {TEACHER_VARIATIONS}"
            )
        tasks.check(self.task)
        declared = {"misleading": ("mislead", "misleading direction"),
                    "coupled": ("couple", "coupled axis")}
        if self.variation in declared:
            field, what = declared[self.variation]
            if getattr(tasks.module(self.task, "teacher").SCRIPT, field) is None:
                raise ImitateError(
                    f"variation={self.variation!r} not accepted for task {self.task!r}: its "
                    f"script declares no {what}; use 'aligned' or 'misaligned'"
                )
        for name in ("spread", "tilt_plane_spread", "tremor", "tremor_angle", "offset"):
            if not getattr(self, name) >= 0:
                raise ImitateError(f"{name}={getattr(self, name)!r} not accepted: a value >= 0")


@dataclass(frozen=True, eq=False)
class TeacherMotion:
    """A scripted recording session: continuous object poses over ``[0, duration]``.

    Attributes:
        config: the configuration it was drawn from.
        objects: the tool and the target.
        boundaries: ``(n_demos, 2)`` start and end time of each demonstration [s]; outside them
            the objects are held still (up to tremor).
        duration: length of the session [s].
        paths: per demonstration, the waypoint curve of the phase ``u`` in [0, 1]; it gives
            ``(target bottom (3), target tilt, tool top - target rim (3), tool tilt)`` [m, rad].
        warps: ``(n_demos, _WARP_GRID)`` phase ``u`` at evenly spaced times over each
            demonstration (monotone, 0 to 1).
        tilt_planes: ``(n_demos,)`` azimuth of the tool's tilt plane [rad].
        tremor: ``(2, 4, _TREMOR_WAVES, 3)`` per object, per channel (x, y, z, tilt), the
            sinusoids' amplitude, frequency [Hz] and phase [rad].
        places: where the script's places stand through each demonstration: ``places[i]`` for
            demonstration ``i`` (from the middle of the stillness before it to the middle of
            the one after it).
    """

    config: TeacherConfig
    objects: tuple[str, str]
    boundaries: np.ndarray
    duration: float
    paths: tuple[CubicHermiteSpline, ...]
    warps: np.ndarray
    tilt_planes: np.ndarray
    tremor: np.ndarray
    places: tuple[tuple[Place, ...], ...]

    @property
    def watched(self) -> tuple[str, ...]:
        """What the robot tracks: the tool, the target, then the places."""
        return (*self.objects, *(p.name for p in self.places[0]))

    def place_poses(self, times: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """The places' frames at ``times`` ``(n,)`` [s], as :meth:`poses` gives the objects'
        (bottom centre, upright): each moves in the middle of the stillness between two
        demonstrations."""
        times = np.atleast_1d(np.asarray(times, dtype=float))
        moves = (self.boundaries[1:, 0] + self.boundaries[:-1, 1]) / 2  # mid-stillness [s]
        demo = np.searchsorted(moves, times, side="right")
        return {p.name: (np.array([self.places[d][k].pos for d in demo]).reshape(-1, 3),
                         np.tile((1.0, 0.0, 0.0, 0.0), (len(times), 1)))
                for k, p in enumerate(self.places[0])}

    def phase(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Which demonstration is under way and how far, at ``times``.

        Args:
            times: ``(n,)`` [s].

        Returns:
            ``(demo (n,) int, u (n,))``: the index of the demonstration in progress or last
            finished (the first one before it starts) and its phase in [0, 1].
        """
        times = np.asarray(times, dtype=float)
        starts, ends = self.boundaries[:, 0], self.boundaries[:, 1]
        demo = np.clip(np.searchsorted(starts, times, side="right") - 1, 0, len(starts) - 1)
        rel = np.clip((times - starts[demo]) / (ends[demo] - starts[demo]), 0.0, 1.0)
        grid = np.linspace(0.0, 1.0, self.warps.shape[1])
        u = np.array([np.interp(r, grid, self.warps[d]) for d, r in zip(demo, rel, strict=True)])
        return demo, u

    def poses(self, times: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
        """Ground-truth poses of the tool and target frames (bottom centre, z along the axis).

        Args:
            times: ``(n,)`` [s].

        Returns:
            ``{object: (pos (n, 3) [m], quat (n, 4) wxyz)}`` in the world frame.
        """
        times = np.atleast_1d(np.asarray(times, dtype=float))
        demo, u = self.phase(times)
        state = np.array([self.paths[d](x) for d, x in zip(demo, u, strict=True)])
        shake = _tremor(self.tremor, times)  # (2, n, 4)
        tool, target = self.objects
        target_tilt = state[:, 3] + shake[1, :, 3]
        target_axis = np.stack(
            [np.zeros_like(target_tilt), -np.sin(target_tilt), np.cos(target_tilt)], axis=1
        )
        rim = state[:, :3] + shapes.SHAPES[target].height * target_axis
        tool_tilt = state[:, 7] + shake[0, :, 3]
        plane = self.tilt_planes[demo]
        tool_axis = np.stack(
            [
                -np.sin(plane) * np.sin(tool_tilt),
                np.cos(plane) * np.sin(tool_tilt),
                np.cos(tool_tilt),
            ],
            axis=1,
        )
        tool_pos = rim + state[:, 4:7] - shapes.SHAPES[tool].height * tool_axis
        # Rz(plane) Rx(-tilt) maps z onto tool_axis; Rx(tilt) leans the target towards -y.
        tool_rot = Rotation.from_euler("ZX", np.stack([plane, -tool_tilt], axis=1))
        target_rot = Rotation.from_euler("X", target_tilt[:, None])
        return {
            tool: (tool_pos + shake[0, :, :3], tool_rot.as_quat(scalar_first=True)),
            target: (state[:, :3] + shake[1, :, :3], target_rot.as_quat(scalar_first=True)),
        }

    def demonstration_frames(self, times: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """Ground-truth frames of the tool and the target at the ``times`` inside each
        demonstration.

        Args:
            times: ``(n,)`` session times [s].

        Returns:
            Per demonstration, ``(position (2, m, 3) [m], axis (2, m, 3))``: the frames' origins
            (bottom centres) and unit long axes in the world frame, objects in
            ``objects`` order (tool, target), at the ``m`` of ``times`` within its start and end.
        """
        times = np.asarray(times, dtype=float)
        frames = []
        for start, end in self.boundaries:
            poses = self.poses(times[(times >= start) & (times <= end)])
            position = np.array([poses[obj][0] for obj in self.objects])
            axis = np.array(
                [
                    Rotation.from_quat(poses[obj][1], scalar_first=True).as_matrix()[:, :, 2]
                    for obj in self.objects
                ]
            )
            frames.append((position, axis))
        return frames


def script_demonstrations(config: TeacherConfig = TeacherConfig()) -> TeacherMotion:
    """Draw a recording session of ``config.n_demos`` demonstrations of ``config.task``.

    The same config (seed included) gives the same motion.
    """
    script: Script = tasks.module(config.task, "teacher").SCRIPT
    rng = np.random.default_rng(config.seed)
    rows = script.waypoints
    critical = list(script.agree_rows)
    u = np.array([row[0] for row in rows])
    nominal = np.array([[*row[1], np.radians(row[2]), *row[3], np.radians(row[4])] for row in rows])
    spread = (
        np.array(
            [
                [row[5][0]] * 3
                + [np.radians(row[5][1])]
                + list(np.broadcast_to(row[5][2], 3))
                + [np.radians(row[5][3])]
                for row in rows
            ]
        )
        * config.spread
    )
    misaligned = config.variation == "misaligned"
    if misaligned:  # the task space outside the critical phase as the nominal everywhere
        outside = np.setdiff1d(np.arange(len(rows)), critical)
        spread[outside, _TASK_COLUMNS] = 0.0
        spread[critical, script.offset_axis] = 0.0  # along the offsets' axis: they alone
    rests = nominal[0] + spread[0] * rng.standard_normal((config.n_demos + 1, nominal.shape[1]))
    draws, warps, boundaries = [], [], []
    t = rng.uniform(*config.pause)
    for _ in range(config.n_demos):
        draws.append(rng.standard_normal(nominal.shape))
        warps.append(_time_warp(rng, config.speed_variation))
        duration = rng.uniform(*config.duration)
        boundaries.append((t, t + duration))
        t += duration + rng.uniform(*config.pause)
    noises = np.array(draws)
    # One swing per demonstration, wide or narrow, spread around the nominal swing: the offsets
    # are centred over the session (n > 1), so the mean swing is the nominal one, and scaled by
    # sqrt(n / (n - 1)) so that they spread as much as independent draws.
    swing = noises[:, script.swing_rows[0], 4:7]
    if config.n_demos > 1:
        swing = (swing - swing.mean(axis=0)) * np.sqrt(config.n_demos / (config.n_demos - 1))
    noises[:, script.swing_rows, 4:7] = swing[:, None]
    # In the critical phase, along ``column``: evenly over +-half, shuffled.
    column, half = {
        "misaligned": (script.offset_axis, config.offset),
        "misleading": _mislead_in_values(script.mislead),
        "coupled": script.couple or (0, 0.0),
    }.get(config.variation, (0, 0.0))
    offsets = np.zeros(config.n_demos)
    if config.n_demos > 1:
        even = np.linspace(-1.0, 1.0, config.n_demos) * half * config.spread
        offsets = even[np.random.default_rng([config.seed, 1]).permutation(config.n_demos)]
    moves = _place_moves(config, script)
    paths = []
    for i, noise in enumerate(noises):
        values = nominal + spread * noise
        values[0], values[-1] = rests[i], rests[i + 1]
        # In the critical phase the target moves as scripted (nominal), off by its offset at
        # the phase's start.
        values[critical[1], :3] += values[critical[0], :3] - nominal[critical[0], :3]
        values[critical, column] += offsets[i]
        values[list(script.placed_rows), :2] += moves[i]
        # Shape-preserving (no overshoot between waypoints), starting and ending at rest.
        slopes = PchipInterpolator(u, values).derivative()(u)
        slopes[[0, -1]] = 0.0
        paths.append(CubicHermiteSpline(u, values, slopes))
    amplitude = np.array([config.tremor] * 3 + [config.tremor_angle]) * np.sqrt(2 / _TREMOR_WAVES)
    shape = (2, 4, _TREMOR_WAVES)
    tremor = np.stack(
        [
            np.broadcast_to(amplitude[None, :, None], shape),
            rng.uniform(*_TREMOR_BAND, shape),
            rng.uniform(0, 2 * np.pi, shape),
        ],
        axis=-1,
    )
    return TeacherMotion(
        config=config,
        objects=script.objects,
        boundaries=np.array(boundaries),
        duration=float(t),
        paths=tuple(paths),
        warps=np.array(warps),
        tilt_planes=config.tilt_plane_spread * rng.standard_normal(config.n_demos),
        tremor=tremor,
        places=tuple(tuple(replace(p, x=round(p.x + dx, 6), y=round(p.y + dy, 6))
                           for p in script.places) for dx, dy in moves),
    )


def _place_moves(config: TeacherConfig, script: Script) -> np.ndarray:
    """Each demonstration's move of the script's places ``(n_demos, 2)`` [m]: evenly over
    ``+-place_spread`` (times ``spread``) in x and in y, each shuffled on its own (from a stream of
    their own: the rest of the session is drawn as without them)."""
    rng = np.random.default_rng([config.seed, 2])
    even = np.linspace(-1.0, 1.0, config.n_demos) if config.n_demos > 1 else np.zeros(1)
    half = np.multiply(script.place_spread, config.spread)
    return np.stack([rng.permutation(even) * half[0], rng.permutation(even) * half[1]], axis=1)


def _mislead_in_values(mislead: tuple[int, float] | None) -> tuple[int, float]:
    """A script's ``mislead`` in the paths' units: the tilt columns' half range in radians."""
    if mislead is None:
        return 0, 0.0
    column, half = mislead
    return column, np.radians(half) if column in (3, 7) else half


def _time_warp(rng: np.random.Generator, variation: float) -> np.ndarray:
    """Phase over evenly spaced times ``(_WARP_GRID,)``: smooth, monotone, 0 to 1.

    The local speed is ``1 + variation * g`` times the mean, ``g`` a random smooth function
    with ``max |g| = 1`` (three harmonics).
    """
    x = np.linspace(0.0, 1.0, _WARP_GRID)
    k = np.arange(1, 4)[:, None]
    g = (
        rng.standard_normal((3, 1))
        / k
        * np.sin(2 * np.pi * k * x + rng.uniform(0, 2 * np.pi, (3, 1)))
    ).sum(0)
    speed = 1.0 + variation * g / np.abs(g).max()
    phase = np.concatenate([[0.0], np.cumsum((speed[1:] + speed[:-1]) / 2)])
    return phase / phase[-1]


def _tremor(waves: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Tremor ``(n_objects, n, 4)`` (x, y, z [m], tilt [rad]) at ``times (n,)`` [s]."""
    amp, freq, phase = waves[..., 0], waves[..., 1], waves[..., 2]
    angle = 2 * np.pi * freq[..., None] * times + phase[..., None]  # (obj, ch, wave, n)
    return np.einsum("ocw,ocwn->onc", amp, np.sin(angle))
