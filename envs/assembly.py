"""Scene assembly with ``mujoco.MjSpec``: room, robot, teacher, a task's two objects, its places
and contents (:class:`Content`), obstacles and fixtures.

One model serves both halves of the experiment. The task's objects, the tool and the target, are
free bodies held by weld constraints, either in the robot's hands (tool right, target left) or
in the teacher's (tool in its left hand, which the robot sees on its own right); :func:`hold`
switches.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from numbers import Real
from typing import Any, Protocol

import mujoco
import numpy as np

from imitate import defaults
from imitate.envs.collision import INSIDE, inside
from imitate.errors import ImitateError
from imitate.models import humanoid, model_path, objects, scene, shapes, teacher
from imitate.taskspace import EQ1, WORLD, TaskSpace

HOLDERS = ("robot", "teacher")
# How the tool meets the target: never (each keeps clear of the other's hulls), or it goes into
# it (the tool keeps clear of the target's walls and floor instead: :func:`clearance_geoms`).
CONTACTS = ("apart", "inside")
OBSTACLE_SHAPES = defaults.OBSTACLE_SHAPES
# Highest an obstacle's bottom may float above the table top [m]: up to the robot's shoulders.
OBSTACLE_MAX_LIFT = defaults.OBSTACLE_MAX_LIFT
GRASP_RANGE = shapes.GRASP_RANGE  # [m] above each object's bottom, by object name
# Which hand (and grip site) holds the tool and which the target, for each holder.
HANDS = {
    "robot": ((humanoid.RIGHT_HAND, humanoid.RIGHT_GRIP), (humanoid.LEFT_HAND, humanoid.LEFT_GRIP)),
    "teacher": (
        (teacher.HAND["left"], teacher.GRIP["left"]),
        (teacher.HAND["right"], teacher.GRIP["right"]),
    ),
}


def _finite(values) -> tuple[float, ...] | None:
    """``values`` as floats if they are finite real numbers, else ``None``."""
    try:
        items = tuple(values)
        if all(isinstance(v, Real) and not isinstance(v, bool) and math.isfinite(v) for v in items):
            return tuple(float(v) for v in items)
    except (TypeError, OverflowError):
        pass
    return None


@dataclass(frozen=True)
class Obstacle:
    """A box or upright cylinder standing on the table.

    Attributes:
        shape: ``"box"`` or ``"cylinder"``.
        pos: ``(3,)`` centre in the world frame [m].
        size: half extents ``(3,)`` for a box, ``(radius, half height)`` for a cylinder [m],
            positive.

    Its whole footprint lies on the table top and its bottom at or above the top, at most
    ``OBSTACLE_MAX_LIFT`` above it (a :class:`Fixture` may stand anywhere). Whether it clears
    the robot and the objects it holds is :func:`check_clearance`'s question (it needs the
    assembled scene).
    """

    shape: str
    pos: tuple[float, float, float]
    size: tuple[float, ...]

    kind = "obstacle"  # what the messages call it

    def __post_init__(self):
        if self.shape not in OBSTACLE_SHAPES:
            raise ImitateError(
                f"{self.kind} shape {self.shape!r} unknown; accepted: {OBSTACLE_SHAPES}"
            )
        n_size = 3 if self.shape == "box" else 2
        pos, size = _finite(self.pos), _finite(self.size)
        if pos is None or len(pos) != 3 or size is None or len(size) != n_size or min(size) <= 0:
            raise ImitateError(
                f"{self.kind} {self.shape} with pos={self.pos} size={self.size} not accepted: "
                f"pos needs 3 finite values [m] and size {n_size} finite positive values [m]"
            )
        object.__setattr__(self, "pos", pos)
        object.__setattr__(self, "size", size)
        self._check_place()

    def _check_place(self) -> None:
        """Raise ``ImitateError`` unless it stands on the table."""
        pos, size = self.pos, self.size
        (x0, x1), (y0, y1), top = scene.TABLE_X, scene.TABLE_Y, scene.TABLE_HEIGHT
        (x, y, z), half_x, half_y = pos, size[0], size[1 if self.shape == "box" else 0]
        if not (x0 <= x - half_x and x + half_x <= x1 and y0 <= y - half_y and y + half_y <= y1):
            raise ImitateError(
                f"obstacle {self.shape} at pos={pos} size={size} is outside the table: its "
                f"footprint x {x - half_x:.3f}..{x + half_x:.3f}, y {y - half_y:.3f}.."
                f"{y + half_y:.3f} must lie within the table top x {x0}..{x1}, y {y0}..{y1} "
                "(a Fixture may stand off it)"
            )
        bottom = z - size[-1]
        if not top - 1e-3 <= bottom <= top + OBSTACLE_MAX_LIFT:
            raise ImitateError(
                f"obstacle {self.shape} at pos={pos} size={size} is outside the table: its bottom "
                f"(z - half height = {bottom:.3f}) must be at or above the table top z={top} "
                f"and at most {OBSTACLE_MAX_LIFT} m above it (a Fixture may stand off it)"
            )


@dataclass(frozen=True)
class Place:
    """An object that stands still, upright, on the table or raised above it on a post: a
    landmark a task space may be relative to (a :class:`~imitate.taskspace.Relative` term names
    it). Its body and shape are those of its name; the planner keeps clear of its hulls (and its
    post), as of an obstacle.

    Attributes:
        name: Its shape, one of :data:`imitate.models.shapes.SHAPES`; its body's name.
        x, y: Where its bottom's centre stands over the table top [m].
        lift: How far above the table top its bottom is, on a grey post as wide as it [m].
    """

    name: str
    x: float
    y: float
    lift: float = 0.0

    def __post_init__(self):
        if self.name not in shapes.SHAPES:
            raise ImitateError(f"place {self.name!r} unknown; accepted: {list(shapes.SHAPES)}")
        xy = _finite((self.x, self.y, self.lift))
        radius = max(r for r, _ in shapes.SHAPES[self.name].profile)
        (x0, x1), (y0, y1) = scene.TABLE_X, scene.TABLE_Y
        if xy is None or not (x0 + radius <= xy[0] <= x1 - radius
                              and y0 + radius <= xy[1] <= y1 - radius
                              and 0 <= xy[2] <= OBSTACLE_MAX_LIFT):
            raise ImitateError(
                f"place {self.name} at x={self.x!r}, y={self.y!r}, lift={self.lift!r} not "
                f"accepted: its footprint (radius {radius} m) must lie within the table top x "
                f"{x0}..{x1}, y {y0}..{y1}, its bottom 0..{OBSTACLE_MAX_LIFT} m above it"
            )
        object.__setattr__(self, "x", xy[0])
        object.__setattr__(self, "y", xy[1])
        object.__setattr__(self, "lift", xy[2])

    @property
    def pos(self) -> tuple[float, float, float]:
        """Its bottom's centre [m]."""
        return self.x, self.y, scene.TABLE_HEIGHT + self.lift


@dataclass(frozen=True)
class Fixture(Obstacle):
    """A static box or upright cylinder that need not stand on the table: a shelf over the
    pour, a plate under the glass. Built, seen by the planner's collision cost and by the
    physics exactly as an :class:`Obstacle` (a ``SceneConfig``'s ``obstacles`` take both); only
    its place is free, its bottom at or above the floor. Whether it clears the robot and the
    objects it holds at the start is :func:`check_clearance`'s question, as for an obstacle."""

    kind = "fixture"

    def _check_place(self) -> None:
        """Raise ``ImitateError`` if its bottom is below the floor."""
        bottom = self.pos[2] - self.size[-1]
        if bottom < 0:
            raise ImitateError(
                f"fixture {self.shape} at pos={self.pos} size={self.size} is below the floor: "
                f"its bottom (z - half height = {bottom:.3f}) must be at or above the floor z=0; "
                "raise its z"
            )


class Content(Protocol):
    """What a task adds to its scene beyond its objects and places (the pour's liquid): built
    into the model, placed at every reset of its env, and changed for drawing."""

    @property
    def settings(self) -> dict[str, Any]:
        """The task env's arguments it is made from (``{"particles": 60}``)."""
        ...

    def add(self, spec: mujoco.MjSpec) -> None:
        """Add its bodies to ``spec``."""
        ...

    def reset(
        self, model: mujoco.MjModel, data: mujoco.MjData, rng: np.random.Generator | None
    ) -> None:
        """Put its bodies where an episode starts (the objects held, before kinematics)."""
        ...

    def show(self, model: mujoco.MjModel) -> None:
        """Change ``model`` (a copy for drawing) so that people see it."""
        ...


@dataclass(frozen=True)
class SceneConfig:
    """What the scene contains.

    Attributes:
        teacher: include the teacher mannequin across the table.
        contents: what the task adds to the scene (:class:`Content`).
        obstacles: obstacles on the table and fixtures (:class:`Fixture`) off it.
        holder: who holds the objects at the start, ``"robot"`` or ``"teacher"``.
        objects: the tool (held in the robot's right hand) and the target (left), names of
            :data:`imitate.models.shapes.SHAPES`.
        grasps: height along the tool and along the target at which each is held [m], see
            ``GRASP_RANGE``.
        contact: how the tool meets the target, one of :data:`CONTACTS`: ``"inside"``, it
            goes into it (a stick into the glass), the clearance keeping the tool clear of the
            target's walls instead of its solid hulls (:func:`clearance_geoms`).
        places: objects standing still on the table (:class:`Place`), neither of ``objects``.
        space: the task space the planner maps the scene through (its places are among
            ``places``).
    """

    teacher: bool = True
    contents: tuple[Content, ...] = ()
    obstacles: tuple[Obstacle, ...] = field(default_factory=tuple)
    holder: str = "robot"
    objects: tuple[str, ...] = (shapes.BOTTLE, shapes.GLASS)
    grasps: tuple[float, ...] = (shapes.GRASP[shapes.BOTTLE], shapes.GRASP[shapes.GLASS])
    contact: str = "apart"
    places: tuple[Place, ...] = ()
    space: TaskSpace = EQ1

    def __post_init__(self):
        if not isinstance(self.teacher, bool | np.bool_):
            raise ImitateError(f"teacher={self.teacher!r} not accepted: True or False")
        if self.contact not in CONTACTS:
            raise ImitateError(f"contact={self.contact!r} not accepted: one of {CONTACTS}")
        if self.holder not in HOLDERS or (self.holder == "teacher" and not self.teacher):
            raise ImitateError(
                f"holder={self.holder!r} not accepted: one of {HOLDERS} ('teacher' needs "
                f"teacher=True)"
            )
        if len(self.objects) != 2 or not set(self.objects) <= set(GRASP_RANGE):
            raise ImitateError(
                f"objects={self.objects!r} not accepted: a tool and a target of "
                f"{list(GRASP_RANGE)}"
            )
        if len(self.grasps) != 2:
            raise ImitateError(f"grasps={self.grasps!r} not accepted: two heights [m]")
        for obj, value in zip(self.objects, self.grasps, strict=True):
            check_grasp(obj, value)
        for obstacle in self.obstacles:
            if not isinstance(obstacle, Obstacle):
                raise ImitateError(
                    f"obstacles must be Obstacle or Fixture instances, got {obstacle!r}"
                )
        names = [p.name for p in self.places if isinstance(p, Place)]
        if len(names) < len(self.places) or len(set(names)) < len(names) or set(names) & set(
                self.objects):
            raise ImitateError(
                f"places={self.places!r} not accepted: Place instances of distinct objects, "
                f"none of {self.objects}"
            )
        missing = sorted(set(self.space.places) - set(names) - {WORLD})
        if missing:
            raise ImitateError(f"the task space is relative to {missing}, not in places {names}")


def check_grasp(obj: str, height: float) -> None:
    """Raise ``ImitateError`` unless ``height`` [m] is in ``GRASP_RANGE[obj]``."""
    low, high = GRASP_RANGE[obj]
    if _finite((height,)) is None or not low <= height <= high:
        raise ImitateError(
            f"{obj} grasp height {height!r} m not accepted: a height in [{low}, {high}] m "
            f"above the {obj}'s bottom"
        )


def check_clearance(config: SceneConfig, clearance: float = 0.0) -> None:
    """Raise ``ImitateError`` if an obstacle, fixture or place of ``config`` comes closer than
    ``clearance`` [m] (overlaps, for 0) to the robot or an object it holds at the start: the
    rest pose, the objects at their grasps. The message names the obstacle, the geom and the
    distance. Obstacles may touch the table and each other."""
    if not config.obstacles and not config.places:
        return
    model = build_model(dataclasses.replace(config, teacher=False, contents=(), holder="robot"))
    data = mujoco.MjData(model)
    data.qpos[[model.joint(j).qposadr[0] for j in humanoid.JOINTS]] = humanoid.rest_pose()
    hold(model, data, "robot")
    geoms = clearance_geoms(model)
    names = {g: model.geom(g).name for g in geoms}
    obstacle_geoms = [g for g in geoms if names[g].startswith(scene.OBSTACLE_PREFIX)]
    place_geoms = {p: [g for g in geoms if names[g].startswith(f"{p.name}_hull_")]
                   for p in config.places}
    others = [g for g in geoms if g not in obstacle_geoms and names[g] != scene.TABLE_TOP
              and not any(g in found for found in place_geoms.values())]
    for place, found in place_geoms.items():
        for o in found:
            for g in others:
                distance = mujoco.mj_geomDistance(model, data, o, g, clearance + 0.01, None)
                if distance < clearance:
                    raise ImitateError(
                        f"place {place.name} at x={place.x}, y={place.y} comes "
                        f"{distance * 1000:.1f} mm to {names[g]!r} at the start (rest pose, "
                        "objects at their grasps): it must stand clear of the robot and the "
                        "objects it holds"
                    )
    for obstacle, o in zip(config.obstacles, obstacle_geoms, strict=True):
        for g in others:
            distance = mujoco.mj_geomDistance(model, data, o, g, clearance + 0.01, None)
            if distance < clearance:
                where = (f"overlaps {names[g]!r} by {-distance * 1000:.1f} mm" if distance < 0
                         else f"is {distance * 1000:.1f} mm from {names[g]!r}")
                raise ImitateError(
                    f"{obstacle.kind} {obstacle.shape} at pos={obstacle.pos} "
                    f"size={obstacle.size} "
                    f"{where} at the start (rest pose, objects at their grasps): it must stand "
                    f"{f'{clearance * 1000:.0f} mm ' if clearance else ''}clear of the robot and "
                    "the objects it holds"
                )


def build_spec(config: SceneConfig = SceneConfig()) -> mujoco.MjSpec:
    """The scene as an editable ``MjSpec``."""
    parts = ["scene.xml", "humanoid.xml"] + (["teacher.xml"] if config.teacher else [])
    includes = "".join(f'<include file="{model_path(part)}"/>' for part in parts)
    spec = mujoco.MjSpec.from_string(f'<mujoco model="{config.objects[0]}">{includes}</mujoco>')
    for obj in config.objects:
        objects.add_container(spec, spec.worldbody, obj, shapes.SHAPES[obj])
    for place in config.places:
        shape = shapes.SHAPES[place.name]
        body = objects.add_container(spec, spec.worldbody, place.name, shape, fixed=True)
        body.pos = place.pos
        body.mocap = config.holder == "teacher"  # the teacher moves its places between demos
        if place.lift > 0:  # its post, from the table top to its bottom
            body.add_geom(
                name=f"{place.name}_hull_post", type=mujoco.mjtGeom.mjGEOM_CYLINDER,
                size=(shape.profile[0][0], place.lift / 2, 0), pos=(0, 0, -place.lift / 2),
                rgba=(0.45, 0.42, 0.40, 1),
            )
    if config.contact == "inside":
        spec.add_text(name=INSIDE, data=" ".join(config.objects))
    for content in config.contents:
        content.add(spec)
    for i, obstacle in enumerate(config.obstacles):
        body = spec.worldbody.add_body(name=f"{scene.OBSTACLE_PREFIX}{i}", pos=obstacle.pos)
        kind = (
            mujoco.mjtGeom.mjGEOM_BOX if obstacle.shape == "box" else mujoco.mjtGeom.mjGEOM_CYLINDER
        )
        body.add_geom(
            name=f"{scene.OBSTACLE_PREFIX}{i}",
            type=kind,
            size=(*obstacle.size, 0)[:3],
            rgba=(0.45, 0.42, 0.40, 1),
        )
    for holder in HOLDERS if config.teacher else ("robot",):
        for obj, (hand, _) in grips(holder, config.objects).items():
            spec.add_equality(
                name=scene.weld_name(obj, hand),
                type=mujoco.mjtEq.mjEQ_WELD,
                objtype=mujoco.mjtObj.mjOBJ_BODY,
                name1=hand,
                name2=obj,
                active=holder == config.holder,
                solref=(0.004, 1.0),
            )
            spec.add_exclude(bodyname1=hand, bodyname2=obj)
    return spec


def build_model(config: SceneConfig = SceneConfig()) -> mujoco.MjModel:
    """Compile the scene; the welds are set to hold each object at its configured grasp."""
    return _with_grasps(build_spec(config).compile(), config)


def planning_model(config: SceneConfig = SceneConfig()) -> mujoco.MjModel:
    """The scene as the planner sees it: the robot holding the bottle and glass, the table and
    ``config``'s obstacles, with the :func:`clearance_geoms` only (no teacher, no liquid, no
    drawn-only or container-wall geoms for ``mj_kinematics`` to place). Every body keeps
    the whole scene's mass and inertia, so poses, Jacobians and distances are the whole scene's
    bit for bit."""
    config = dataclasses.replace(config, teacher=False, contents=(), holder="robot")
    spec = build_spec(config)
    whole = spec.compile()
    keep = {whole.geom(g).name for g in clearance_geoms(whole)}
    for geom in list(spec.geoms):
        if geom.name not in keep:
            spec.delete(geom)
    for body in spec.bodies:
        if body.name != "world":
            b = whole.body(body.name)
            body.mass, body.ipos, body.iquat, body.inertia = b.mass[0], b.ipos, b.iquat, b.inertia
            body.explicitinertial = True
    return _with_grasps(spec.compile(), config)


def _with_grasps(model: mujoco.MjModel, config: SceneConfig) -> mujoco.MjModel:
    """``model`` with its welds set to hold each object at ``config``'s grasp."""
    for holder in HOLDERS if config.teacher else ("robot",):
        for obj, height in zip(config.objects, config.grasps, strict=True):
            set_grasp(model, holder, obj, height)
    return model


def grips(holder: str, objs: tuple[str, ...]) -> dict[str, tuple[str, str]]:
    """``{object: (hand body, grip site)}`` of ``holder`` for the tool and target ``objs``."""
    return dict(zip(objs, HANDS[holder], strict=True))


def objects_in(model: mujoco.MjModel) -> tuple[str, str]:
    """The tool and target of a scene built by :func:`build_model` (its first two free
    bodies, in the order they were added)."""
    names = [model.body(model.jnt_bodyid[j]).name for j in range(model.njnt)
             if model.jnt_type[j] == mujoco.mjtJoint.mjJNT_FREE]
    found = [n for n in names if n in shapes.SHAPES]
    return found[0], found[1]


def grasp_pose(model: mujoco.MjModel, holder: str, obj: str, height: float):
    """Pose of ``obj`` in its holding hand's frame when held ``height`` [m] above its bottom.

    Returns:
        ``(pos (3,) [m], quat (4,) wxyz)``.
    """
    _, site = grips(holder, objects_in(model))[obj]
    site_pos, site_quat = model.site(site).pos, model.site(site).quat
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, site_quat)
    return site_pos - rot.reshape(3, 3) @ np.array([0.0, 0.0, height]), site_quat.copy()


def set_grasp(model: mujoco.MjModel, holder: str, obj: str, height: float) -> None:
    """Make ``holder``'s weld hold ``obj`` at ``height`` [m] above its bottom (no recompile)."""
    check_grasp(obj, height)
    hand, _ = grips(holder, objects_in(model))[obj]
    pos, quat = grasp_pose(model, holder, obj, height)
    eq = model.equality(scene.weld_name(obj, hand))
    # Weld data: anchor (3), pose of body2 in body1's frame (pos 3, quat 4), torque scale.
    eq.data[:3] = 0.0
    eq.data[3:6] = pos
    eq.data[6:10] = quat
    eq.data[10] = 1.0


def hold(model: mujoco.MjModel, data: mujoco.MjData, holder: str) -> None:
    """Activate ``holder``'s welds, deactivate the others', and move the objects into its hands."""
    if holder not in HOLDERS:
        raise ImitateError(f"holder={holder!r} not accepted: one of {HOLDERS}")
    held = objects_in(model)
    for name in HANDS:
        for obj, (hand, _) in grips(name, held).items():
            eq_id = mujoco.mj_name2id(
                model, mujoco.mjtObj.mjOBJ_EQUALITY, scene.weld_name(obj, hand)
            )
            if eq_id < 0 and name == holder:
                raise ImitateError(f"holder={holder!r} is not in this scene (built without it)")
            if eq_id >= 0:
                data.eq_active[eq_id] = name == holder
    mujoco.mj_kinematics(model, data)
    for obj, (hand, _) in grips(holder, held).items():
        eq = model.equality(scene.weld_name(obj, hand))
        hand_pos, hand_quat = data.body(hand).xpos, data.body(hand).xquat
        pos, quat = np.zeros(3), np.zeros(4)
        mujoco.mju_mulPose(pos, quat, hand_pos, hand_quat, eq.data[3:6], eq.data[6:10])
        qadr = model.jnt_qposadr[model.joint(obj).id]
        data.qpos[qadr : qadr + 3] = pos
        data.qpos[qadr + 3 : qadr + 7] = quat
        dadr = model.jnt_dofadr[model.joint(obj).id]
        data.qvel[dadr : dadr + 6] = 0.0
    mujoco.mj_kinematics(model, data)


def clearance_geoms(model: mujoco.MjModel) -> list[int]:
    """Ids of the geoms that must keep clear of each other.

    The robot's collision capsules, the objects' hulls, the table top and the obstacles; in a
    scene whose tool goes into its target (``SceneConfig.contact == "inside"``), the target's
    walls and floor too, which the tool keeps clear of instead of the target's hulls. Pairs
    among them are filtered by ``imitate.envs.collision.CollisionPairs.between``.
    """
    root = model.body(humanoid.ROOT_BODY).id
    robot = {b for b in range(model.nbody) if model.body_rootid[b] == root}
    target = (inside(model) or (-1, -1))[1]
    keep = []
    for g in range(model.ngeom):
        name = model.geom(g).name
        body, physical = model.geom_bodyid[g], model.geom_contype[g]
        if ((body in robot or body == target) and physical) or (
            "_hull_" in name or name == scene.TABLE_TOP or name.startswith(scene.OBSTACLE_PREFIX)
        ):
            keep.append(g)
    return keep
