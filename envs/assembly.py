"""Scene assembly with ``mujoco.MjSpec``: room, robot, teacher, bottle, glass, liquid, obstacles.

One model serves both halves of the experiment. The bottle and glass are free bodies held by
weld constraints, either in the robot's hands (bottle right, glass left) or in the teacher's
(bottle in its left hand, which the robot sees on its own right); :func:`hold` switches.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import mujoco
import numpy as np

from imitate.errors import ImitateError
from imitate.models import humanoid, model_path, objects, scene, teacher

HOLDERS = ("robot", "teacher")
OBSTACLE_SHAPES = ("box", "cylinder")
MAX_PARTICLES = 120  # what fits in the bottle below its shoulder
GRASP_RANGE = {objects.BOTTLE: (0.05, 0.13), objects.GLASS: (0.03, 0.08)}  # [m] from the bottom
# Which hand (and grip site) holds which object, for each holder.
GRASPS = {
    "robot": {
        objects.BOTTLE: (humanoid.RIGHT_HAND, humanoid.RIGHT_GRIP),
        objects.GLASS: (humanoid.LEFT_HAND, humanoid.LEFT_GRIP),
    },
    "teacher": {
        objects.BOTTLE: (teacher.HAND["left"], teacher.GRIP["left"]),
        objects.GLASS: (teacher.HAND["right"], teacher.GRIP["right"]),
    },
}


@dataclass(frozen=True)
class Obstacle:
    """A box or upright cylinder standing on the table.

    Attributes:
        shape: ``"box"`` or ``"cylinder"``.
        pos: ``(3,)`` centre in the world frame [m]; its footprint must be on the table top and
            its bottom at or above it.
        size: half extents ``(3,)`` for a box, ``(radius, half height)`` for a cylinder [m].
    """

    shape: str
    pos: tuple[float, float, float]
    size: tuple[float, ...]

    def __post_init__(self):
        if self.shape not in OBSTACLE_SHAPES:
            raise ImitateError(
                f"obstacle shape {self.shape!r} unknown; accepted: {OBSTACLE_SHAPES}"
            )
        n_size = 3 if self.shape == "box" else 2
        if len(self.pos) != 3 or len(self.size) != n_size or min(self.size) <= 0:
            raise ImitateError(
                f"obstacle {self.shape} with pos={self.pos} size={self.size}: pos needs 3 "
                f"values [m] and size {n_size} positive values [m]"
            )
        (x0, x1), (y0, y1) = scene.TABLE_X, scene.TABLE_Y
        x, y, z = self.pos
        half_height = self.size[2] if self.shape == "box" else self.size[1]
        if not (x0 <= x <= x1 and y0 <= y <= y1) or z - half_height < scene.TABLE_HEIGHT - 1e-3:
            raise ImitateError(
                f"obstacle at pos={self.pos} is outside the table: its centre must have x in "
                f"[{x0}, {x1}] and y in [{y0}, {y1}] and its bottom (z - half height = "
                f"{z - half_height:.3f}) must be at or above the table top z={scene.TABLE_HEIGHT}"
            )


@dataclass(frozen=True)
class SceneConfig:
    """What the scene contains.

    Attributes:
        teacher: include the teacher mannequin across the table.
        particles: number of liquid spheres in the bottle, 0..``MAX_PARTICLES``.
        obstacles: obstacles on the table.
        holder: who holds the bottle and glass at the start, ``"robot"`` or ``"teacher"``.
        bottle_grasp: height along the bottle at which it is held [m], see ``GRASP_RANGE``.
        glass_grasp: height along the glass at which it is held [m], see ``GRASP_RANGE``.
    """

    teacher: bool = True
    particles: int = 60
    obstacles: tuple[Obstacle, ...] = field(default_factory=tuple)
    holder: str = "robot"
    bottle_grasp: float = 0.09
    glass_grasp: float = 0.05

    def __post_init__(self):
        if not isinstance(self.particles, int | np.integer) or not (
            0 <= self.particles <= MAX_PARTICLES
        ):
            raise ImitateError(
                f"particles={self.particles!r} not accepted: an integer in 0..{MAX_PARTICLES}"
            )
        if self.holder not in HOLDERS or (self.holder == "teacher" and not self.teacher):
            raise ImitateError(
                f"holder={self.holder!r} not accepted: one of {HOLDERS} ('teacher' needs "
                f"teacher=True)"
            )
        for obj, value in ((objects.BOTTLE, self.bottle_grasp), (objects.GLASS, self.glass_grasp)):
            check_grasp(obj, value)
        for obstacle in self.obstacles:
            if not isinstance(obstacle, Obstacle):
                raise ImitateError(f"obstacles must be Obstacle instances, got {obstacle!r}")


def check_grasp(obj: str, height: float) -> None:
    """Raise ``ImitateError`` unless ``height`` [m] is in ``GRASP_RANGE[obj]``."""
    low, high = GRASP_RANGE[obj]
    if not low <= height <= high:
        raise ImitateError(
            f"{obj} grasp height {height!r} m not accepted: a height in [{low}, {high}] m "
            f"above the {obj}'s bottom"
        )


def build_spec(config: SceneConfig = SceneConfig()) -> mujoco.MjSpec:
    """The scene as an editable ``MjSpec``."""
    parts = ["scene.xml", "humanoid.xml"] + (["teacher.xml"] if config.teacher else [])
    includes = "".join(f'<include file="{model_path(part)}"/>' for part in parts)
    spec = mujoco.MjSpec.from_string(f'<mujoco model="pouring">{includes}</mujoco>')
    for obj, shape in objects.SHAPES.items():
        objects.add_container(spec, spec.worldbody, obj, shape)
    objects.add_particles(spec, config.particles)
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
        for obj, (hand, _) in GRASPS[holder].items():
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
    model = build_spec(config).compile()
    for holder in HOLDERS if config.teacher else ("robot",):
        set_grasp(model, holder, objects.BOTTLE, config.bottle_grasp)
        set_grasp(model, holder, objects.GLASS, config.glass_grasp)
    return model


def grasp_pose(model: mujoco.MjModel, holder: str, obj: str, height: float):
    """Pose of ``obj`` in its holding hand's frame when held ``height`` [m] above its bottom.

    Returns:
        ``(pos (3,) [m], quat (4,) wxyz)``.
    """
    _, site = GRASPS[holder][obj]
    site_pos, site_quat = model.site(site).pos, model.site(site).quat
    rot = np.zeros(9)
    mujoco.mju_quat2Mat(rot, site_quat)
    return site_pos - rot.reshape(3, 3) @ np.array([0.0, 0.0, height]), site_quat.copy()


def set_grasp(model: mujoco.MjModel, holder: str, obj: str, height: float) -> None:
    """Make ``holder``'s weld hold ``obj`` at ``height`` [m] above its bottom (no recompile)."""
    check_grasp(obj, height)
    hand, _ = GRASPS[holder][obj]
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
    for name, grasps in GRASPS.items():
        for obj, (hand, _) in grasps.items():
            eq_id = mujoco.mj_name2id(
                model, mujoco.mjtObj.mjOBJ_EQUALITY, scene.weld_name(obj, hand)
            )
            if eq_id < 0 and name == holder:
                raise ImitateError(f"holder={holder!r} is not in this scene (built without it)")
            if eq_id >= 0:
                data.eq_active[eq_id] = name == holder
    mujoco.mj_kinematics(model, data)
    for obj, (hand, _) in GRASPS[holder].items():
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


def fill_bottle(model: mujoco.MjModel, data: mujoco.MjData, rng: np.random.Generator | None = None):
    """Place every particle at rest inside the bottle (at its current pose), with a small jitter."""
    n = particle_count(model)
    if n == 0:
        return
    slots = objects.particle_slots(objects.BOTTLE_SHAPE, n)
    if rng is not None:
        slots[:, :2] += rng.uniform(-0.2, 0.2, (n, 2)) * objects.PARTICLE_RADIUS
    mujoco.mj_kinematics(model, data)
    body = data.body(objects.BOTTLE)
    world = body.xpos + slots @ body.xmat.reshape(3, 3).T
    for i in range(n):
        joint = model.joint(f"{objects.PARTICLE_PREFIX}{i}")
        qadr, dadr = model.jnt_qposadr[joint.id], model.jnt_dofadr[joint.id]
        data.qpos[qadr : qadr + 7] = (*world[i], 1.0, 0.0, 0.0, 0.0)
        data.qvel[dadr : dadr + 6] = 0.0


def particle_count(model: mujoco.MjModel) -> int:
    """Number of liquid particles in ``model``."""
    prefix = objects.PARTICLE_PREFIX
    return sum(model.body(i).name.startswith(prefix) for i in range(model.nbody))


def clearance_geoms(model: mujoco.MjModel) -> list[int]:
    """Ids of the geoms that must keep clear of each other.

    The robot's collision capsules, the bottle's and glass's hulls, the table top and the
    obstacles. Pairs among them are filtered by ``imitate.envs.collision.CollisionPairs.between``.
    """
    root = model.body(humanoid.ROOT_BODY).id
    robot = {b for b in range(model.nbody) if model.body_rootid[b] == root}
    keep = []
    for g in range(model.ngeom):
        name = model.geom(g).name
        if (model.geom_bodyid[g] in robot and model.geom_contype[g]) or (
            "_hull_" in name or name == scene.TABLE_TOP or name.startswith(scene.OBSTACLE_PREFIX)
        ):
            keep.append(g)
    return keep
