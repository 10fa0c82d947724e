"""The pour's liquid: free, frictionless spheres in the tool (:class:`Liquid`, a scene content,
see :class:`~imitate.envs.assembly.Content`): built into the scene, filled into the tool at
rest at every reset, drawn larger where people watch it."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

from imitate.envs.assembly import objects_in
from imitate.envs.pour.options import MAX_PARTICLES
from imitate.errors import ImitateError
from imitate.models.objects import PHYSICAL, STIFF_SOLREF, VISUAL_GROUP
from imitate.models.shapes import SHAPES, ContainerShape

__all__ = ["PARTICLE_PREFIX", "PARTICLE_RADIUS", "PARTICLE_RGBA", "Liquid", "particle_bodies",
           "particle_geoms", "particle_slots"]

PARTICLE_PREFIX = "particle_"  # a particle's body, free joint and geom: particle_<i>
PARTICLE_RADIUS = 0.005  # [m]
PARTICLE_DENSITY = 1000.0  # [kg/m^3], water
# Red juice: it stands out on the white robot, the grey floor and the beige table, and its hue
# is far from the bottle's green and the glass's blue.
PARTICLE_RGBA = (0.82, 0.06, 0.12, 1.0)
# What people see of it; only the copy of the model that draws it is changed, so the physics
# (PARTICLE_RADIUS, masses, contacts) stays as it is.
PARTICLE_DRAWN_RADIUS = 0.008  # [m]


@dataclass(frozen=True)
class Liquid:
    """``particles`` spheres of liquid in the tool.

    Attributes:
        particles: How many, 0..``MAX_PARTICLES`` (what fits in the bottle below its shoulder).
    """

    particles: int

    def __post_init__(self):
        if not isinstance(self.particles, int | np.integer) or not (
            0 <= self.particles <= MAX_PARTICLES
        ):
            raise ImitateError(
                f"particles={self.particles!r} not accepted: an integer in 0..{MAX_PARTICLES}"
            )

    @property
    def settings(self) -> dict[str, Any]:
        """The env's arguments it is made from."""
        return {"particles": int(self.particles)}

    def add(self, spec: mujoco.MjSpec) -> None:
        """Its particles, free bodies of the world (placed at :meth:`reset`)."""
        for i in range(self.particles):
            body = spec.worldbody.add_body(name=f"{PARTICLE_PREFIX}{i}")
            body.add_freejoint(name=f"{PARTICLE_PREFIX}{i}")
            body.add_geom(
                name=f"{PARTICLE_PREFIX}{i}", type=mujoco.mjtGeom.mjGEOM_SPHERE,
                size=(PARTICLE_RADIUS, 0, 0), density=PARTICLE_DENSITY, rgba=PARTICLE_RGBA,
                condim=1, solref=STIFF_SOLREF, contype=PHYSICAL, conaffinity=PHYSICAL,
                group=VISUAL_GROUP,
            )

    def reset(
        self, model: mujoco.MjModel, data: mujoco.MjData, rng: np.random.Generator | None
    ) -> None:
        """Every particle at rest inside the tool (at its current pose), with a small jitter
        drawn from ``rng`` (none without)."""
        if self.particles == 0:
            return
        n, tool = self.particles, objects_in(model)[0]
        slots = particle_slots(SHAPES[tool], n)
        if rng is not None:
            slots[:, :2] += rng.uniform(-0.2, 0.2, (n, 2)) * PARTICLE_RADIUS
        mujoco.mj_kinematics(model, data)
        body = data.body(tool)
        world = body.xpos + slots @ body.xmat.reshape(3, 3).T
        for i in range(n):
            joint = model.joint(f"{PARTICLE_PREFIX}{i}")
            qadr, dadr = model.jnt_qposadr[joint.id], model.jnt_dofadr[joint.id]
            data.qpos[qadr : qadr + 7] = (*world[i], 1.0, 0.0, 0.0, 0.0)
            data.qvel[dadr : dadr + 6] = 0.0

    def show(self, model: mujoco.MjModel) -> None:
        """Draw the particles larger in ``model`` (for drawing only)."""
        for g in particle_geoms(model):
            model.geom_size[g, 0] = PARTICLE_DRAWN_RADIUS
            model.geom_rbound[g] = PARTICLE_DRAWN_RADIUS


def particle_bodies(model: mujoco.MjModel) -> np.ndarray:
    """Ids ``(n,)`` of the liquid's bodies in ``model``, in order."""
    return np.array([b for b in range(model.nbody)
                     if model.body(b).name.startswith(PARTICLE_PREFIX)], dtype=int)


def particle_geoms(model: mujoco.MjModel) -> np.ndarray:
    """Ids ``(n,)`` of the liquid's geoms in ``model``, in order."""
    return np.array([g for g in range(model.ngeom)
                     if model.geom(g).name.startswith(PARTICLE_PREFIX)], dtype=int)


def particle_slots(shape: ContainerShape, count: int) -> np.ndarray:
    """Non-overlapping rest positions for ``count`` particles inside ``shape``, bottom up.

    Returns:
        ``(count, 3)`` positions in the container frame [m].
    """
    pitch = 2.05 * PARTICLE_RADIUS
    reach = shape.profile[0][0] - shape.wall / 2 - PARTICLE_RADIUS * 1.1 - pitch / 3
    grid = np.arange(-reach, reach + 1e-9, pitch)
    layer = np.array([(x, y) for x in grid for y in grid if np.hypot(x, y) <= reach])
    n_layers = -(-count // len(layer))
    z = shape.wall + PARTICLE_RADIUS * 1.1 + pitch * np.arange(n_layers)
    slots = np.array([(x, y, h) for h in z for x, y in layer])[:count]
    # Alternate layers are offset by half a pitch so the pile settles without stacking columns.
    slots[:, :2] += (np.floor((slots[:, 2] - z[0]) / pitch + 0.5) % 2)[:, None] * pitch / 4
    return slots
