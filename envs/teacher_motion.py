"""The teacher: scripted bimanual pouring demonstrations, and the mannequin that performs them.

:func:`script_demonstrations` draws ``n_demos`` pouring movements (lift, bring the bottle over the
glass, tilt and pour, return) as a person would repeat them: spread by a few cm while
transporting, a few mm and degrees while pouring, each on its own smooth monotone time warp, with
a little tremor throughout and at least one second of stillness between demonstrations; or, with
``TeacherConfig(variation="misaligned")``, the same swing every time and a pour whose position
varies by centimetres across the glass (a teacher whose variance is not where the task is).
:func:`teacher_pour` pours a demonstration with liquid, to check that the script pours. The
result, a :class:`TeacherMotion`, gives the ground-truth object poses at any time; :func:`show`
puts the objects there and draws the mannequin's arms holding them.

The teacher holds the bottle in its left hand, which the robot facing it sees on its own right
(mirror correspondence), and tilts the bottle's top towards the glass (world ``+y``).

Each arm is three mocap bodies. Given where a hand should be, :func:`pose_arm` places the hand
there and draws upper arm and forearm by two-link inverse kinematics, elbow down and out, so a
video reads as a person holding the objects.
"""

from __future__ import annotations

from dataclasses import dataclass

import mujoco
import numpy as np
from scipy.interpolate import CubicHermiteSpline, PchipInterpolator
from scipy.spatial.transform import Rotation

from imitate import defaults
from imitate.envs.assembly import GRASPS, SceneConfig, build_model, fill_bottle, hold
from imitate.errors import ImitateError
from imitate.models import humanoid, objects, scene, teacher

_YAW = np.pi  # the mannequin faces the robot (-x)


def shoulder_position(side: str) -> np.ndarray:
    """World position ``(3,)`` [m] of the teacher's ``side`` (``"left"``/``"right"``) shoulder."""
    if side not in teacher.SIDES:
        raise ImitateError(f"side {side!r} not accepted: one of {teacher.SIDES}")
    x, y, z = teacher.SHOULDER[side]
    c, s = np.cos(_YAW), np.sin(_YAW)
    return np.array(scene.TEACHER_POS) + np.array([c * x - s * y, s * x + c * y, z])


def hand_pose_for_object(
    model: mujoco.MjModel, obj: str, obj_pos: np.ndarray, obj_quat: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """World pose of the teacher's hand that holds ``obj`` at ``(obj_pos, obj_quat)``.

    Inverts the weld's grasp pose (set by ``imitate.envs.assembly.set_grasp``).

    Returns:
        ``(pos (3,) [m], quat (4,) wxyz)`` of the hand body.
    """
    hand, _ = GRASPS["teacher"][obj]
    eq = model.equality(scene.weld_name(obj, hand))
    inv_pos, inv_quat = np.zeros(3), np.zeros(4)
    mujoco.mju_negPose(inv_pos, inv_quat, eq.data[3:6], eq.data[6:10])
    pos, quat = np.zeros(3), np.zeros(4)
    mujoco.mju_mulPose(
        pos, quat, np.asarray(obj_pos, float), np.asarray(obj_quat, float), inv_pos, inv_quat
    )
    return pos, quat


def pose_arm(
    model: mujoco.MjModel,
    data: mujoco.MjData,
    side: str,
    hand_pos: np.ndarray,
    hand_quat: np.ndarray,
) -> None:
    """Put the teacher's ``side`` hand at ``(hand_pos [m], hand_quat wxyz)`` and draw its arm.

    A target beyond the arm's reach keeps the hand where asked and stretches the arm towards it.
    """
    shoulder = shoulder_position(side)
    wrist = np.asarray(hand_pos, dtype=float)
    l1, l2 = teacher.UPPER_ARM_LENGTH, teacher.FOREARM_LENGTH
    reach = wrist - shoulder
    dist = np.clip(np.linalg.norm(reach), abs(l1 - l2) + 1e-3, l1 + l2 - 1e-4)
    along = reach / max(np.linalg.norm(reach), 1e-9)
    # Elbow bends down and away from the body: the hint is the world's down plus outward.
    outward = 1.0 if side == "right" else -1.0  # teacher faces -x: its right is +y
    hint = np.array([0.0, 0.4 * outward, -1.0])
    bend = hint - hint.dot(along) * along
    bend /= np.linalg.norm(bend)
    cos_a = (l1**2 + dist**2 - l2**2) / (2 * l1 * dist)
    elbow = shoulder + l1 * (cos_a * along + np.sqrt(max(0.0, 1 - cos_a**2)) * bend)
    wrist_reached = elbow + l2 * _unit(wrist - elbow)
    _set_mocap(model, data, teacher.UPPER_ARM[side], shoulder, _segment_quat(shoulder, elbow))
    _set_mocap(model, data, teacher.FOREARM[side], elbow, _segment_quat(elbow, wrist_reached))
    _set_mocap(model, data, teacher.HAND[side], wrist, np.asarray(hand_quat, dtype=float))


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(np.linalg.norm(v), 1e-9)


def _segment_quat(start: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Orientation whose local -z points from ``start`` to ``end``."""
    z = -_unit(end - start)
    helper = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = _unit(_cross(helper, z))
    y = _cross(z, x)
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.column_stack([x, y, z]).ravel())
    return quat


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of two 3-vectors: its arithmetic without its generality, which took two
    thirds of the teacher's posing time per frame."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def _set_mocap(model, data, body: str, pos, quat) -> None:
    mocap_id = model.body_mocapid[model.body(body).id]
    data.mocap_pos[mocap_id] = pos
    data.mocap_quat[mocap_id] = quat


# --- Scripted demonstrations -------------------------------------------------------------------

TEACHER_OBJECTS = (objects.BOTTLE, objects.GLASS)
_KEYS = ("glass", "glass_tilt", "mouth", "bottle_tilt")
# The nominal pour as waypoints in a demonstration's phase u in [0, 1]: the glass bottom [m], the
# glass tilt towards the bottle [deg], the bottle's mouth relative to the glass rim centre [m] and
# the bottle tilt towards the glass [deg]; with each waypoint's spread over demonstrations (one
# standard deviation, [m] and [deg]; the mouth's either one value or per axis x, y, z). The first
# and last rows are the rest pose, shared with the previous and next demonstration. The mouth is
# placed relative to the glass, so the bottle's position relative to the glass varies by
# millimetres while pouring and by centimetres while transporting.
# - Swing (rows 1-2): the bottle swings out beside and in front of the glass, towards the robot
#   (world -x), still upright, above and beside the glass in the robot's view; how far it swings
#   varies most (6 cm, against 2-2.5 cm sideways and up). Followed exactly, the swing brings the
#   robot's bottle into its chest by centimetres (paper Fig. 8): the reproduction has to leave
#   the demonstrated mean, where the demonstrations varied. The swings spread around the
#   nominal one (their offsets are centred over the session): drawn independently, the mean of
#   five varies by 2.7 cm itself, and in 5 of 30 sessions (seeds 20-49) the reproduction
#   without the collision cost then came less than 2 cm into the chest or missed it.
# - Pour (rows 4-5): the bottle is held at a nearly constant tilt (126-130 deg) over the glass
#   while the teacher lifts both hands a little (the glass rises 5 cm): steady relative to the
#   glass, so the attractors can follow it closely, yet never still, so the stillness
#   segmentation does not cut a demonstration in two. The tilt empties the bottle: its shoulder
#   (radius 34 to 16 mm over 45 mm of height) slopes towards the neck by only 6 deg at a tilt of
#   118 deg, where the last particles came to rest on it and rolled out over the glass's edge
#   as the bottle tilted back; at 128 deg it slopes by 16 deg and drains.
# - Return (rows 6-7): the bottle tilts back before it is lowered, so the pour ends gently.
_SWING = (0.06, 0.02, 0.025)  # spread of the mouth on the swing: towards the robot, sideways, up
_WAYPOINTS = (
    # u,  glass bottom,        tilt, mouth - rim,           tilt, spreads (glass, tilt, mouth, tilt)
    (0.00, (1.21, 0.11, 1.00), 0.0, (0.00, -0.24, 0.165), 0.0, (0.020, 0.0, 0.006, 0.0)),
    (0.12, (1.19, 0.07, 1.04), 3.0, (-0.31, -0.16, 0.20), 3.0, (0.020, 1.5, _SWING, 5.0)),
    (0.24, (1.19, 0.07, 1.04), 3.0, (-0.44, -0.12, 0.28), 5.0, (0.020, 1.5, _SWING, 5.0)),
    (0.36, (1.18, 0.06, 1.02), 8.0, (-0.12, -0.05, 0.13), 62.0, (0.020, 2.0, 0.040, 5.0)),
    (0.52, (1.18, 0.05, 1.05), 12.0, (0.00, -0.025, 0.040), 126.0, (0.020, 1.0, 0.003, 1.0)),
    (0.68, (1.18, 0.02, 1.10), 14.0, (0.00, -0.020, 0.035), 130.0, (0.003, 1.0, 0.003, 1.0)),
    (0.80, (1.18, -0.01, 1.14), 6.0, (0.00, -0.05, 0.07), 95.0, (0.020, 2.0, 0.010, 8.0)),
    (0.92, (1.19, 0.07, 1.03), 4.0, (0.00, -0.10, 0.13), 30.0, (0.020, 2.0, 0.020, 8.0)),
    (1.00, (1.21, 0.11, 1.00), 0.0, (0.00, -0.24, 0.165), 0.0, (0.020, 0.0, 0.006, 0.0)),
)
_SWING_ROWS = (1, 2)  # a demonstration swings wide or narrow as a whole: one draw for both
_POUR_ROWS = (4, 5)  # the glass keeps its offset from the nominal while the bottle pours
# Where the demonstrations vary (``TeacherConfig.variation``):
# - "aligned": as the waypoints' spreads say, centimetres in the swing and millimetres in the
#   pour, so that the demonstrations agree where the task is (the paper's premise behind eq. 21:
#   invariant = important) and the reproduction may give way in the swing (Fig. 8-9).
# - "misaligned": the premise turned round, to test it instead of assuming it. Outside the pour
#   everything that moves the task space (the mouth relative to the rim, both tilts) is the
#   nominal in every demonstration: they agree in the swing, where nothing depends on them.
#   While pouring, each holds the mouth off the nominal along the stream (world y, the way the
#   bottle tilts: nearer to or further across the glass's axis) by its own offset, and only by
#   it; the offsets spread evenly over +-``pour_offset`` (25 mm) in a seeded order, so the pour
#   varies by centimetres where the liquid has to land. Bounded, not drawn, so that every
#   demonstration still pours: in physics (:func:`teacher_pour`, 60 particles) every
#   demonstration of seeds 0-9 put at least 0.967 of the liquid into the glass with +-25 mm
#   (the mouth from 47 mm short of the glass's axis, outside the rim's 40 mm inner radius, to
#   4 mm past it), the outermost of seed 6 only 0.900 with +-30 mm (success is 0.9) and that of
#   seed 0 0.817 with +-35 mm. Not along the rim's tangent (world x): that is the robot's depth,
#   which its stereo resolves worst; a teacher varied by +-25 mm there was perceived as varying
#   as much in the swing as in the pour (GMR position standard deviation 14 mm in both), so
#   eq. 21 could not tell them apart. The glass's own position (outside the task space), the
#   time warps and the tremor vary as in "aligned".
TEACHER_VARIATIONS = defaults.TEACHER_VARIATIONS
_TASK_COLUMNS = slice(3, 8)  # glass tilt, mouth - rim (3), bottle tilt: what moves the task space
_POUR_AXIS = 5  # the mouth's world y (in the waypoints' columns): along the stream
_WARP_GRID = 2001  # samples of a demonstration's time warp
_TREMOR_BAND = (6.0, 11.0)  # [Hz], physiological tremor
_TREMOR_WAVES = 6  # sinusoids summed per tremor channel


@dataclass(frozen=True)
class TeacherConfig:
    """How the teacher demonstrates.

    Attributes:
        n_demos: number of demonstrations.
        duration: range ``(low, high)`` [s] each demonstration's duration is drawn from.
        pause: range ``(low, high)`` [s] of the stillness between demonstrations; also the
            stillness before the first and after the last demonstration is drawn from it.
        spread: scale of the spatial variation between demonstrations: 1 gives the spreads of
            the nominal waypoints (up to 6 cm while transporting, 3 mm and 1 deg while
            pouring).
        tilt_plane_spread: standard deviation of the azimuth of the plane the bottle tilts in
            [rad] (0: it tilts straight across the robot's view).
        speed_variation: amplitude of the time warp: the local speed is
            ``1 +- speed_variation`` times a demonstration's mean speed, in [0, 0.9].
        tremor: standard deviation of the hands' tremor, positions [m].
        tremor_angle: standard deviation of the tremor of the tilt angles [rad].
        variation: where the demonstrations vary (:data:`TEACHER_VARIATIONS`): ``"aligned"``
            (centimetres in the swing, millimetres in the pour: they agree where the task is)
            or ``"misaligned"`` (the swing the same in every demonstration, the pour's position
            spread across the glass by ``pour_offset``: they agree where it is not), to test
            the premise that what the demonstrations keep invariant is what matters.
        pour_offset: with ``"misaligned"``, the half range [m] the mouth's offsets along the
            stream spread evenly over while pouring (times ``spread``): 25 mm still pours into
            the glass, 35 mm spills (see ``TEACHER_VARIATIONS``).
        seed: seed of the ``numpy.random.Generator`` everything is drawn from.
    """

    n_demos: int = 5
    duration: tuple[float, float] = (4.0, 5.0)
    pause: tuple[float, float] = (1.2, 1.6)
    spread: float = 1.0
    tilt_plane_spread: float = np.radians(4.0)
    speed_variation: float = 0.25
    tremor: float = 0.0004
    tremor_angle: float = np.radians(0.15)
    variation: str = defaults.TEACHER_VARIATION
    pour_offset: float = 0.025
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
        for name in ("spread", "tilt_plane_spread", "tremor", "tremor_angle", "pour_offset"):
            if not getattr(self, name) >= 0:
                raise ImitateError(f"{name}={getattr(self, name)!r} not accepted: a value >= 0")


@dataclass(frozen=True, eq=False)
class TeacherMotion:
    """A scripted recording session: continuous object poses over ``[0, duration]``.

    Attributes:
        config: the configuration it was drawn from.
        boundaries: ``(n_demos, 2)`` start and end time of each demonstration [s]; outside them
            the objects are held still (up to tremor).
        duration: length of the session [s].
        paths: per demonstration, the waypoint curve of the phase ``u`` in [0, 1]; it gives
            ``(glass bottom (3), glass tilt, mouth - rim (3), bottle tilt)`` [m, rad].
        warps: ``(n_demos, _WARP_GRID)`` phase ``u`` at evenly spaced times over each
            demonstration (monotone, 0 to 1).
        tilt_planes: ``(n_demos,)`` azimuth of the bottle's tilt plane [rad].
        tremor: ``(2, 4, _TREMOR_WAVES, 3)`` per object, per channel (x, y, z, tilt), the
            sinusoids' amplitude, frequency [Hz] and phase [rad].
    """

    config: TeacherConfig
    boundaries: np.ndarray
    duration: float
    paths: tuple[CubicHermiteSpline, ...]
    warps: np.ndarray
    tilt_planes: np.ndarray
    tremor: np.ndarray

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
        """Ground-truth poses of the bottle and glass frames (bottom centre, z along the axis).

        Args:
            times: ``(n,)`` [s].

        Returns:
            ``{object: (pos (n, 3) [m], quat (n, 4) wxyz)}`` in the world frame.
        """
        times = np.atleast_1d(np.asarray(times, dtype=float))
        demo, u = self.phase(times)
        state = np.array([self.paths[d](x) for d, x in zip(demo, u, strict=True)])
        shake = _tremor(self.tremor, times)  # (2, n, 4)
        glass_tilt = state[:, 3] + shake[1, :, 3]
        glass_axis = np.stack(
            [np.zeros_like(glass_tilt), -np.sin(glass_tilt), np.cos(glass_tilt)], axis=1
        )
        rim = state[:, :3] + objects.GLASS_SHAPE.height * glass_axis
        bottle_tilt = state[:, 7] + shake[0, :, 3]
        plane = self.tilt_planes[demo]
        bottle_axis = np.stack(
            [
                -np.sin(plane) * np.sin(bottle_tilt),
                np.cos(plane) * np.sin(bottle_tilt),
                np.cos(bottle_tilt),
            ],
            axis=1,
        )
        bottle_pos = rim + state[:, 4:7] - objects.BOTTLE_SHAPE.height * bottle_axis
        # Rz(plane) Rx(-tilt) maps z onto bottle_axis; Rx(tilt) leans the glass towards -y.
        bottle_rot = Rotation.from_euler("ZX", np.stack([plane, -bottle_tilt], axis=1))
        glass_rot = Rotation.from_euler("X", glass_tilt[:, None])
        return {
            objects.BOTTLE: (bottle_pos + shake[0, :, :3], bottle_rot.as_quat(scalar_first=True)),
            objects.GLASS: (state[:, :3] + shake[1, :, :3], glass_rot.as_quat(scalar_first=True)),
        }

    def demonstration_frames(self, times: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """Ground-truth frames of the bottle and the glass at the ``times`` inside each
        demonstration.

        Args:
            times: ``(n,)`` session times [s].

        Returns:
            Per demonstration, ``(position (2, m, 3) [m], axis (2, m, 3))``: the frames' origins
            (bottom centres) and unit long axes in the world frame, objects in
            ``TEACHER_OBJECTS`` order, at the ``m`` of ``times`` within its start and end.
        """
        times = np.asarray(times, dtype=float)
        frames = []
        for start, end in self.boundaries:
            poses = self.poses(times[(times >= start) & (times <= end)])
            position = np.array([poses[obj][0] for obj in TEACHER_OBJECTS])
            axis = np.array(
                [
                    Rotation.from_quat(poses[obj][1], scalar_first=True).as_matrix()[:, :, 2]
                    for obj in TEACHER_OBJECTS
                ]
            )
            frames.append((position, axis))
        return frames


def script_demonstrations(config: TeacherConfig = TeacherConfig()) -> TeacherMotion:
    """Draw a recording session of ``config.n_demos`` pouring demonstrations.

    The same config (seed included) gives the same motion.
    """
    rng = np.random.default_rng(config.seed)
    rows = _WAYPOINTS
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
    if misaligned:  # the task space outside the pour as the nominal in every demonstration
        outside = np.setdiff1d(np.arange(len(rows)), _POUR_ROWS)
        spread[outside, _TASK_COLUMNS] = 0.0
        spread[list(_POUR_ROWS), _POUR_AXIS] = 0.0  # along the stream: the offsets alone
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
    swing = noises[:, _SWING_ROWS[0], 4:7]
    if config.n_demos > 1:
        swing = (swing - swing.mean(axis=0)) * np.sqrt(config.n_demos / (config.n_demos - 1))
    noises[:, _SWING_ROWS, 4:7] = swing[:, None]
    offsets = np.zeros(config.n_demos)  # the mouth's along the stream while pouring
    if misaligned and config.n_demos > 1:  # evenly over +-pour_offset, shuffled
        even = np.linspace(-1.0, 1.0, config.n_demos) * config.pour_offset * config.spread
        offsets = even[np.random.default_rng([config.seed, 1]).permutation(config.n_demos)]
    paths = []
    for i, noise in enumerate(noises):
        values = nominal + spread * noise
        values[0], values[-1] = rests[i], rests[i + 1]
        if misaligned:
            values[list(_POUR_ROWS), _POUR_AXIS] += offsets[i]
        # While pouring the glass moves as scripted (nominal), off by its pour-start offset.
        values[_POUR_ROWS[1], :3] += values[_POUR_ROWS[0], :3] - nominal[_POUR_ROWS[0], :3]
        # Shape-preserving (no overshoot between waypoints), starting and ending at rest.
        slopes = PchipInterpolator(u, values).derivative()(u)
        slopes[[0, -1]] = 0.0
        paths.append(CubicHermiteSpline(u, values, slopes))
    amplitude = np.array([config.tremor] * 3 + [config.tremor_angle]) * np.sqrt(2 / _TREMOR_WAVES)
    shape = (len(TEACHER_OBJECTS), 4, _TREMOR_WAVES)
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
        boundaries=np.array(boundaries),
        duration=float(t),
        paths=tuple(paths),
        warps=np.array(warps),
        tilt_planes=config.tilt_plane_spread * rng.standard_normal(config.n_demos),
        tremor=tremor,
    )


def teacher_pour(
    motion: TeacherMotion, demo: int, *, particles: int = 60, settle: float = 0.5, seed: int = 0
) -> float:
    """The teacher's pour in physics: the share of the liquid in the glass after demonstration
    ``demo`` of ``motion`` and ``settle`` [s] more.

    The scene with the teacher holding both objects on its hands' welds, ``particles`` of liquid
    in the bottle (placed with ``seed``'s jitter) and the robot at rest; the hands (mocap bodies)
    follow the script at every physics step from the demonstration's start. A check of the
    script, not part of a run: the scripted poses are what the robot sees, with or without
    liquid.

    Raises:
        ImitateError: ``demo`` is not a demonstration of ``motion``.
    """
    if not 0 <= demo < len(motion.boundaries):
        raise ImitateError(f"demo={demo!r} not accepted: 0..{len(motion.boundaries) - 1}")
    model = build_model(SceneConfig(teacher=True, holder="teacher", particles=particles))
    data = mujoco.MjData(model)
    joints = [model.joint(j).qposadr[0] for j in humanoid.JOINTS]
    data.qpos[joints] = data.ctrl[:] = humanoid.rest_pose()
    start, end = motion.boundaries[demo]
    poses = motion.poses(np.arange(start, end + settle, model.opt.timestep))
    hands = {
        obj: model.body_mocapid[model.body(teacher.HAND[holding_side(obj)]).id]
        for obj in TEACHER_OBJECTS
    }
    for step in range(len(poses[objects.BOTTLE][0])):
        for obj, mocap in hands.items():
            data.mocap_pos[mocap], data.mocap_quat[mocap] = hand_pose_for_object(
                model, obj, poses[obj][0][step], poses[obj][1][step]
            )
        if step == 0:  # the objects into the hands, then the bottle filled
            hold(model, data, "teacher")
            fill_bottle(model, data, np.random.default_rng(seed))
            mujoco.mj_forward(model, data)
        mujoco.mj_step(model, data)
    liquid = [model.body(f"{objects.PARTICLE_PREFIX}{i}").id for i in range(particles)]
    glass = data.body(objects.GLASS)
    local = (data.xpos[liquid] - glass.xpos) @ glass.xmat.reshape(3, 3)
    shape = objects.GLASS_SHAPE
    radius = np.interp(local[:, 2], *np.transpose(shape.profile)[::-1])
    inside = (local[:, 2] > 0) & (local[:, 2] < shape.height) & (np.hypot(*local[:, :2].T) < radius)
    return float(np.mean(inside))


def show(model: mujoco.MjModel, data: mujoco.MjData, poses: dict[str, tuple]) -> None:
    """Put the objects at ``poses`` and draw the teacher's arms holding them; no physics.

    Args:
        model: a scene built with the teacher.
        data: its data; object free joints and the teacher's mocap bodies are written, then
            kinematics are updated for rendering.
        poses: ``{object: (pos (3,) [m], quat (4,) wxyz)}`` of the object frames.
    """
    for obj, (pos, quat) in poses.items():
        joint = model.joint(obj)
        data.qpos[joint.qposadr[0] : joint.qposadr[0] + 7] = (*pos, *quat)
        hand_pos, hand_quat = hand_pose_for_object(model, obj, pos, quat)
        pose_arm(model, data, holding_side(obj), hand_pos, hand_quat)
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)


def holding_side(obj: str) -> str:
    """The teacher's hand (``"left"``/``"right"``) that holds ``obj``."""
    if obj not in GRASPS["teacher"]:
        raise ImitateError(f"object {obj!r} not accepted: one of {tuple(GRASPS['teacher'])}")
    hand = GRASPS["teacher"][obj][0]
    return next(side for side in teacher.SIDES if teacher.HAND[side] == hand)


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
